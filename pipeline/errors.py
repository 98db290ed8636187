"""The pipeline's errors, in a module below everything that raises them: pipeline.config imports
the engines' registry, and the registry raises ConfigError, so neither imports the other for it."""


class ConfigError(ValueError):
    """A bad value in the config; its message is one line naming the key and the value."""


class BadInput(ValueError):
    """A fault of the input that a stage reports in one line (pipeline.cli: exit 2)."""


class DamagedFile(BadInput):
    """A file the pipeline wrote is not what it should be (truncated, edited, of another
    version): the message names it, and the stage that meets it replaces nothing."""


class UnsafeName(BadInput):
    """A name from the config or from a file on disk that cannot become one path component."""


class FileTooLarge(OSError, BadInput):
    """EFBIG: a write beyond the file system's largest file or the process's file-size limit
    (ulimit -f; Python ignores SIGXFSZ, so the write fails): one line, exit 2 (a BadInput)."""

    def __str__(self):
        return (f"{self.filename}: file too large for the file system or the file-size limit "
                "(ulimit -f); raise the limit or choose another paths.root")
