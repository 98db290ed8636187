"""The front door's config: the schema (schema), where the config lives and how a command line
is composed (compose), the checks of its values (checks) and of Hydra's own settings
(hydra_keys); the run given the composed config (hydra_run) and --help (help)."""
from ..errors import ConfigError  # noqa: F401
from ..experiments import config_folders  # noqa: F401
from .checks import (RANGES, check_choices, check_keys, check_limits, check_run,  # noqa: F401
                     check_stamp, config_notes, declared)
from .compose import (CONF_DIR, CONFIG_PATH, IN_CHECKOUT, REPO_ROOT,  # noqa: F401
                      check_experiments, compose, default_root, initialized, overrides_of,
                      sweep_tag, without_hydra)
from .hydra_keys import check_hydra  # noqa: F401
from .schema import (BodyConf, Config, VariantConf, defaults_of, learner_params,  # noqa: F401
                     register_schemas)
