"""ConfigError, in a module of its own: pipeline.config imports the engines' registry (to make
the config group `engine`), and the registry raises it, so neither imports the other for it."""


class ConfigError(ValueError):
    """A bad value in the config; its message is one line naming the key and the value."""
