"""Gymnasium environments (docs/gym.md; extra [gym]): importing it registers
gbgrowth/GrowingReach-v0 (Gymnasium 1.x: gym.make("pipeline.envs:gbgrowth/GrowingReach-v0"));
register_envs is also pyproject.toml's entry point (into the namespace gymnasium gives it)."""
from gymnasium.envs import registration

ID = "gbgrowth/GrowingReach-v0"
ENTRY = "pipeline.envs.growing_reach:GrowingReach"


def register_envs() -> None:
    """Register GrowingReach-v0 (under the namespace gbgrowth, or the one of a plugin loader)."""
    ns = registration.current_namespace  # set by a plugin loader around this call
    if f"{ns or 'gbgrowth'}/GrowingReach-v0" not in registration.registry:
        registration.register(id="GrowingReach-v0" if ns else ID, entry_point=ENTRY)


register_envs()
