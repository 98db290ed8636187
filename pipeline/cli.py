"""Every stage's front door: check the command line, run the stage on the checked config, end
in one line where the input or the place is at fault."""
from __future__ import annotations

import errno
import sys
from pathlib import Path

from . import io, stop
from .check import PASSED, SWEEP, check
from .config import ConfigError
from .config.hydra_run import COMPOSED, MODE, composed_once, known_mode
from .fingerprint import CodeChanged
from .io import BadInput
from .planned import mark_checked

__all__ = ["check", "finish", "main", "hydra_run", "snapshot", "disk_message"]


def hydra_run() -> tuple[list[str], str | None, int]:
    """(overrides, multirun group, job number) of the running Hydra job; ([], None, 0) outside."""
    import hashlib

    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    try:
        hc = HydraConfig.get()
    except ValueError:
        return [], None, 0
    overrides = list(hc.overrides.task)
    if hc.mode != RunMode.MULTIRUN:
        return overrides, None, 0
    group = "sweep-" + hashlib.sha256(str(hc.sweep.dir).encode()).hexdigest()[:16]
    return overrides, group, int(hc.job.num)


# what a full disk, a read-only folder or a missing permission raise: a fault of the place, named
DISK = {errno.ENOSPC: "no space left on the device", errno.EDQUOT: "disk quota exceeded",
        errno.EROFS: "read-only file system", errno.EACCES: "permission denied",
        errno.EPERM: "operation not permitted"}


def finish(run, cfg, record: bool = True) -> None:
    """Run a stage and exit with its status: bad input, edited code or a faulty folder is one
    line, exit 2; a signal stops the workers, exit 130, 143, 129 (record=False: no snapshot)."""
    with stop.armed():
        try:  # no write or delete through a link leading elsewhere
            io.confine(cfg.paths.root if cfg is not None else None)
            rc = run(cfg)
            if rc in (0, 1) and record:  # it ran (1: some trials failed or inputs are missing)
                snapshot(cfg)
        except (ConfigError, FileNotFoundError, NotADirectoryError, BadInput, CodeChanged) as err:
            print(f"error: {err}", file=sys.stderr)
            rc = 2
        except OSError as err:
            if err.errno not in DISK:
                raise
            print(f"error: {disk_message(err)}", file=sys.stderr)
            rc = 2
        except MemoryError:
            print("error: out of memory; run fewer workers or shorter trials", file=sys.stderr)
            rc = 2
        except KeyboardInterrupt as err:
            from . import execute  # (its process pools: not imported by a stage that has none)

            execute.stop_pools()
            how = "interrupted" if not isinstance(err, stop.Stopped) else f"stopped by {err}"
            print(f"{how}: finished work is cached; run the same command again to resume",
                  file=sys.stderr, flush=True)
            rc = stop.exit_status(err)
        finally:
            io.confine(None)
    if rc in (0, 1) and record:  # the stage ran (1: some trials failed or inputs are missing)
        for marker, trials, root in PASSED:
            mark_checked(marker, trials, root)
    PASSED.clear()
    if rc:
        sys.exit(rc)


def snapshot(cfg):
    """The resolved config and overrides as Hydra lays them out (.hydra/) under
    paths.out/logs/<stage>/<time>_<tag>/ or the sweep's job folder, after the stage ran."""
    import time

    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from .config import sweep_tag

    if cfg is None or not HydraConfig.initialized():
        return None
    hc = HydraConfig.get()
    folder = Path(hc.runtime.output_dir).resolve()
    if hc.mode != RunMode.MULTIRUN or not folder.is_relative_to(Path(cfg.paths.root).resolve()):
        folder = (Path(cfg.paths.out) / "logs" / hc.job.name
                  / f"{time.strftime('%Y-%m-%d_%H-%M-%S')}_{sweep_tag()}")
    try:
        text = OmegaConf.to_yaml(cfg, resolve=True)
    except Exception:  # an interpolation only a later stage can resolve: kept as written
        text = OmegaConf.to_yaml(cfg)
    io.write_text(folder / ".hydra" / "config.yaml", text)
    io.write_text(folder / ".hydra" / "overrides.yaml",
                  OmegaConf.to_yaml(list(hc.overrides.task)))
    return folder


def disk_message(err: OSError) -> str:
    where = err.filename if err.filename is not None else "a file"
    return f"{where}: {DISK[err.errno]}; free space or choose a writable paths.root"


def main(hydra_main) -> None:
    """Run a stage's @hydra.main function after checking its command line; --help: help_text."""
    stop.install()
    if {"--help", "-h", "--help-all"} & set(sys.argv[1:]):
        import __main__

        from .config.help import help_text

        spec = getattr(__main__, "__spec__", None)
        stage = spec.name if spec else "pipeline"
        if getattr(hydra_main, "__module__", "__main__") != "__main__":  # `gbgrowth <stage>`
            stage = hydra_main.__module__
        text = help_text(stage, sys.argv[1:])
        if sys.argv[0].startswith("gbgrowth "):  # as typed (pipeline.__main__ sets argv[0])
            text = text.replace(f"python -m {stage}", sys.argv[0])
        sys.stdout.write(text)
        sys.exit(0)
    COMPOSED.clear()
    problem = check(sys.argv[1:], hydra_main)
    if problem is not None:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    before = getattr(sys.modules.get(getattr(hydra_main, "__module__", "")), "before_sweep", None)
    if SWEEP and before is not None:  # a stage that says what a whole sweep costs (simulate)
        before(*SWEEP[0])
    with known_mode(MODE), composed_once(COMPOSED):
        hydra_main()
