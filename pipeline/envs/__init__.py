"""Gymnasium environments over gbmodel's bodies and growth (docs/gym.md); needs the extra [gym].

Importing this package registers gbgrowth/GrowingReach-v0. Gymnasium 1.x dropped the loading of
`gymnasium.envs` entry points (0.26 to 0.29 call them when gymnasium is imported), so with it an
id names its module: gym.make("pipeline.envs:gbgrowth/GrowingReach-v0", ...), or `import
pipeline.envs` before gym.make("gbgrowth/GrowingReach-v0", ...). The entry point in
pyproject.toml is register_envs, which registers into the namespace gymnasium gives it.
"""
from gymnasium.envs import registration

ID = "gbgrowth/GrowingReach-v0"
ENTRY = "pipeline.envs.growing_reach:GrowingReach"


def register_envs() -> None:
    """Register GrowingReach-v0 (under the namespace gbgrowth, or the one of a plugin loader)."""
    ns = registration.current_namespace  # set by a plugin loader around this call
    if f"{ns or 'gbgrowth'}/GrowingReach-v0" not in registration.registry:
        registration.register(id="GrowingReach-v0" if ns else ID, entry_point=ENTRY)


register_envs()
