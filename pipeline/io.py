"""Every file the pipeline writes goes through here: atomic, deterministic writes (a temporary
name beside the file, then a rename; Parquet without timestamps, JSON with sorted keys: the same
content gives the same bytes), and the schema of the learning-curve table."""
from __future__ import annotations

import errno
import hashlib
import itertools
import json
import os
import re
import shutil
import socket
import unicodedata
from contextlib import contextmanager, suppress
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

# The learning curve of one trial (and, concatenated, of a figure). External scripts read these.
LABELS = pa.schema([("figure", pa.string()), ("body", pa.string()), ("learner", pa.string()),
                    ("growth", pa.string()), ("growth_period", pa.int64()),
                    ("condition", pa.string()), ("trial", pa.int64())])
CURVE = pa.schema(list(LABELS) + [("epoch", pa.int64()), ("samples", pa.int64())] + [
    (k, pa.float64()) for k in ("size", "abs_error", "rel_error", "heldout_abs_error",
                                "uniform_abs_error", "path_abs_error")])
LABEL_COLUMNS = LABELS.names
CURVE_COLUMNS = CURVE.names
# One trial's curve as the cache keeps it, without labels (aggregate adds its figure's)
TRIAL_CURVE = pa.schema([f for f in CURVE if f.name not in LABELS.names])


class BadInput(ValueError):
    """A fault of the input that a stage reports in one line (pipeline.cli: exit 2)."""


class DamagedFile(BadInput):
    """A file the pipeline wrote is not what it should be; the stage replaces nothing."""


class UnsafeName(BadInput):
    """A name from the config or from a file on disk that cannot become one path component."""


class FileTooLarge(OSError, BadInput):
    """EFBIG: a write beyond the largest file or the file-size limit (Python ignores SIGXFSZ)."""

    def __str__(self):
        return (f"{self.filename}: file too large for the file system or the file-size limit "
                "(ulimit -f); raise the limit or choose another paths.root")


MAX_NAME, MAX_NAME_BYTES = 100, 200  # a name's characters, its UTF-8 bytes (file systems: 255)


def safe_name(key: str, value) -> str:
    """`value` if it can name one file or folder inside an output folder, else UnsafeName."""
    why = None
    if not isinstance(value, str) or not value:
        why = "must be a non-empty name"
    elif "/" in value or "\\" in value:
        why = "must not contain a path separator"
    elif any(unicodedata.category(c) in ("Cc", "Cf", "Cs", "Co", "Cn", "Zl", "Zp")
             for c in value):
        why = "must not contain control, format (bidirectional) or unassigned characters"
    elif value.startswith("."):
        why = "must not start with a dot"
    elif len(value) > MAX_NAME or len(value.encode()) > MAX_NAME_BYTES:
        why = f"must be at most {MAX_NAME} characters and {MAX_NAME_BYTES} bytes (UTF-8)"
    if why:
        raise UnsafeName(f"{key}={value!r}: {why} (it names a file or folder)")
    return value


# ---- every write and delete stays under paths.root ------------------------------------------
_ROOT: list[Path] = []  # the root a stage confines its writes to (pipeline.cli.finish)
_ALSO: set[Path] = set()  # single files outside it a stage writes on purpose (allow)


def confine(root) -> None:
    _ROOT[:] = [] if root is None else [Path(root).resolve()]


@contextmanager
def confined(root):
    """confine(root) within the block (None: as it was), the previous confinement after it."""
    before = list(_ROOT)
    if root is not None:
        confine(root)
    try:
        yield
    finally:
        _ROOT[:] = before


def confined_root() -> Path | None:
    return _ROOT[0] if _ROOT else None


def allow(path) -> None:
    _ALSO.add(Path(path).absolute())


def check_inside(path) -> Path:
    """`path` if the part of it that exists resolves under the confined root, else UnsafeName."""
    path = Path(path)
    if not _ROOT or path.absolute() in _ALSO:
        return path
    full = p = Path(os.path.normpath(path.absolute()))
    while not (p.exists() or p.is_symlink()) and p != p.parent:
        p = p.parent
    real = p.resolve()
    led = real / full.relative_to(p)  # where it leads: its existing part resolved, the rest added
    if led != _ROOT[0] and _ROOT[0] not in led.parents:
        raise UnsafeName(f"{path}: leads outside paths.root={_ROOT[0]} (through {p} -> {real}); "
                         "remove that link")
    return path


# ---- temporary files: exclusive, never through a symlink, named by host and pid ----------------
_HOST = re.sub(r"[^A-Za-z0-9.-]", "_", socket.gethostname()) or "host"
_serial = itertools.count()


def _tmp_name(path):
    """`.<name>~<host>~<pid>~<n>.tmp` beside `path`: whose it is (remove_stale_tmp)."""
    folder, name = os.path.split(os.fspath(path))
    return Path(folder, f".{name}~{_HOST}~{os.getpid()}~{next(_serial)}.tmp")


def _mine_and_dead(name: str) -> bool:
    """Whether the temporary `name` (`...~<host>~<pid>~<n>`) is this host's and its pid is gone."""
    parts = name.rsplit("~", 3)
    if len(parts) != 4 or parts[1] != _HOST or not parts[2].isdigit():
        return False
    try:
        os.kill(int(parts[2]), 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # another user's process
        pass
    return False


def _exclusive(path: str) -> tuple[str, int]:
    """(path, open descriptor) of a new temporary file beside `path` (O_EXCL, O_NOFOLLOW)."""
    while True:
        tmp = os.fspath(_tmp_name(path))
        try:
            return tmp, os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o644)
        except FileExistsError:  # left by a dead process that had our pid: take the next name
            continue


@contextmanager
def _atomic(path, checked: bool = False):
    """Yield (temporary path, descriptor) of a new file renamed onto `path` on success, else
    deleted; OSError names `path`. checked: the caller checked its folder (only a link at the
    name is checked)."""
    path, tmp = os.fspath(path), None
    if not checked or (_ROOT and os.path.islink(path)):
        check_inside(path)  # UnsafeName when it leads outside
    try:
        if not checked:
            os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        try:
            tmp, fd = _exclusive(path)
        except FileNotFoundError:
            if not checked:
                raise
            os.makedirs(os.path.dirname(path), exist_ok=True)  # no folder yet
            tmp, fd = _exclusive(path)
        yield tmp, fd
        os.replace(tmp, path)
        tmp = None  # renamed: nothing left to delete
    except OSError as err:
        if err.errno == errno.EFBIG:
            raise FileTooLarge(errno.EFBIG, os.strerror(errno.EFBIG), path) from None
        err.filename = str(Path(path))  # the final file's name, not the temporary one's
        raise err from None
    finally:
        if tmp is not None:
            with suppress(FileNotFoundError):
                os.unlink(tmp)


@contextmanager
def atomic_file(path):
    """Yield a binary file object on a new file beside `path`, renamed onto it on success."""
    with _atomic(path) as (_, fd), os.fdopen(fd, "wb") as fh:
        yield fh


_FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)  # no room for what a writer writes


@contextmanager
def atomic_path(path):
    """atomic_file for a writer that wants a file name (matplotlib): yield the new file's path."""
    with _atomic(path) as (tmp, fd):
        os.close(fd)
        try:
            yield tmp
        except Exception as err:  # the writer's cleanup raised again over a full disk's error
            cause = err  # (matplotlib's PDF writer: a zlib.error): the disk's error it is
            while cause is not None and getattr(cause, "errno", None) not in _FULL:
                cause = cause.__context__
            raise (err if cause is None else cause) from None


@contextmanager
def new_dir(final):
    """Yield an empty folder that replaces `final` if the block succeeds (old set aside, new
    one in): a reader, or a process killed at any moment, never sees a mix."""
    final = Path(final)
    check_inside(final)
    final.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_tmp(final.parent)
    tmp, old = (_tmp_name(final.with_name(f"{final.name}.{s}")) for s in ("new", "old"))
    tmp.mkdir()
    try:
        yield tmp
        for attempt in range(5):
            try:
                if final.exists() or final.is_symlink():
                    os.rename(final, old)
                os.rename(tmp, final)
                break
            except OSError as err:  # another run put its set in between our two renames
                if err.errno not in (errno.ENOTEMPTY, errno.EEXIST) or attempt == 4:
                    raise
                shutil.rmtree(old, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
    except OSError as err:
        raise _as_final(err, tmp, final)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _as_final(err: OSError, tmp: Path, final: Path) -> OSError:
    """`err` (a full disk) naming the file as it will be called, not its temporary folder's."""
    if isinstance(err.filename, str) and err.filename.startswith(f"{tmp}{os.sep}"):
        err.filename = str(final) + err.filename[len(str(tmp)):]
    return err


def write_text(path, text: str) -> None:
    with atomic_file(path) as fh:
        fh.write(text.encode())


_COMPACT = json.JSONEncoder(sort_keys=True, separators=(",", ":"), allow_nan=True)


def dump_json(obj) -> str:
    return json.dumps(obj, sort_keys=True, indent=1) + "\n"


def write_json(path, obj, compact: bool = False) -> None:
    """JSON with sorted keys: indented for people, or compact (for programs: a trial's sidecar)."""
    write_text(path, _COMPACT.encode(obj) + "\n" if compact else dump_json(obj))


def read_json(path, need: tuple = ()) -> dict:
    """The JSON object in `path`, with the keys `need`, else DamagedFile naming the file."""
    try:
        raw = Path(path).read_bytes()
    except IsADirectoryError:
        raise DamagedFile(f"{path}: a folder, not a JSON file") from None
    return parse_json(raw, path, need)


def parse_json(raw: bytes, path, need: tuple = ()) -> dict:
    try:
        obj = json.loads(raw)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError) as err:
        raise DamagedFile(f"{path}: damaged, not valid JSON ({type(err).__name__}: "
                          f"{str(err)[:80]})") from None
    if not isinstance(obj, dict):
        raise DamagedFile(f"{path}: damaged, not a JSON object")
    missing = [k for k in need if k not in obj]
    if missing:
        raise DamagedFile(f"{path}: damaged, lacks {', '.join(map(repr, missing))}")
    return obj


def write_table(path, table: pa.Table, compress: bool = True) -> str:
    """Parquet with fixed settings and no timestamps; returns the SHA-256 of the bytes written."""
    with atomic_file(path) as fh:  # an error (a full disk) names `path`
        data = table_bytes(table, compress)
        fh.write(data)
    return hashlib.sha256(data).hexdigest()


def table_bytes(table: pa.Table, compress: bool = True) -> pa.Buffer:
    """compress=False: a trial's curve (3 to 130 rows), which zstd shrinks by a tenth at most,
    enlarges below about 20 rows, and costs 0.3 ms a trial."""
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd" if compress else "none",
                   compression_level=3 if compress else None)
    return sink.getvalue()


def write_in_checked(path: str, data) -> None:
    """Write `data` (bytes or a buffer) to `path` as atomic_file does, its folder checked."""
    with _atomic(path, checked=True) as (_, fd):
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view):]
        finally:
            os.close(fd)


def read_table(path, columns=None, schema: pa.Schema | None = None) -> pa.Table:
    """The Parquet table in `path` (with `schema`'s columns), else DamagedFile naming it (not
    pq.read_table: its import loads pandas, 0.4 s CPU)."""
    try:
        with pq.ParquetFile(path) as f:
            absent = sorted(set(columns or ()) - set(f.schema_arrow.names))
            if absent:
                raise pa.ArrowInvalid(f"No match for the columns {', '.join(absent)}")
            table = f.read(columns=columns)
    except FileNotFoundError:
        raise
    except (pa.ArrowException, OSError) as err:
        if isinstance(err, OSError) and err.errno is not None:
            raise  # a fault of the place (permissions), not of the file
        raise _damaged(path, err) from None
    return _has_columns(table, path, schema)


def parse_table(data: bytes, path, schema: pa.Schema | None = None, columns=None) -> pa.Table:
    """read_table on the bytes `data` of the file `path`, in this thread (a third of the CPU)."""
    try:
        table = pq.ParquetFile(pa.BufferReader(data)).read(columns=columns, use_threads=False)
    except pa.ArrowException as err:
        raise _damaged(path, err) from None
    return _has_columns(table, path, schema)


def _damaged(path, err) -> DamagedFile:
    return DamagedFile(f"{path}: damaged, not a readable Parquet file "
                       f"({str(err).splitlines()[0][:80]})")


def _has_columns(table: pa.Table, path, schema: pa.Schema | None) -> pa.Table:
    missing = sorted(set(schema.names) - set(table.column_names)) if schema is not None else ()
    if missing:
        raise DamagedFile(f"{path}: damaged, lacks the columns {', '.join(missing)}")
    return table


def frame_to_table(df) -> pa.Table:
    return pa.Table.from_pandas(df, preserve_index=False)


_NUMPY_OF = {pa.int64(): np.dtype(np.int64), pa.float64(): np.dtype(np.float64)}


def trial_curve_table(result: dict) -> pa.Table:
    """One trial's learning curve (a worker's result) in the TRIAL_CURVE schema, each column an
    array of its numpy type as its buffer (the same bytes; pa.array imports pandas: 0.6 s CPU)."""
    def column(values, type_):
        a = np.asarray(values)
        if a.ndim == 1 and a.dtype == _NUMPY_OF.get(type_):
            a = np.ascontiguousarray(a)
            return pa.Array.from_buffers(type_, len(a), [None, pa.py_buffer(a)])
        return pa.array(a, type=type_)

    return pa.Table.from_arrays([column(result[f.name], f.type) for f in TRIAL_CURVE],
                                schema=TRIAL_CURVE)


def remove_stale_tmp(folder, recursive: bool = False) -> list[Path]:
    """Delete (and return) the temporary files and sets a killed process of this host left."""
    gone, folder = [], Path(folder)
    if not folder.is_dir():
        return gone
    check_inside(folder)
    for tmp in (folder.rglob if recursive else folder.glob)(".*~*~*~*.tmp"):
        if not _mine_and_dead(tmp.name[:-len(".tmp")]):
            continue
        if tmp.is_dir() and not tmp.is_symlink():
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            try:
                tmp.unlink(missing_ok=True)
            except OSError as err:  # a read-only folder: the leftover stays, never read
                if err.errno not in (errno.EROFS, errno.EACCES, errno.EPERM):
                    raise
                continue
        gone.append(tmp)
    return gone


# ---- a stage's outputs replaced as one set -------------------------------------------------------
@contextmanager
def new_set(folder):
    """Yield a new, empty folder (in `.<name>.sets/`) for a stage's whole output set; on success
    `folder` becomes a symlink to it in one rename: a reader (set_of) never sees a mix."""
    folder = Path(folder)
    sets = folder.parent / f".{folder.name}.sets"
    check_inside(folder)
    if sets.is_symlink():
        raise UnsafeName(f"{sets}: a link; the sets of {folder.name} are a folder of their own "
                         "(remove the link)")
    check_inside(sets)
    sets.mkdir(parents=True, exist_ok=True)
    remove_stale_tmp(folder.parent)  # a switching link a killed run left beside the figures
    remove_leaked_sets(folder)
    fresh = _tmp_name(sets / "set")
    fresh.mkdir()
    try:
        yield fresh
        done = fresh.with_name(fresh.name[:-len(".tmp")].lstrip("."))  # finished: not a temp
        os.rename(fresh, done)
        old = set_of(folder) if folder.is_symlink() else None
        if folder.is_dir() and not folder.is_symlink():  # the old layout: a plain folder
            old = sets / f"legacy-{done.name}"
            os.rename(folder, old)
        link = _tmp_name(folder)
        os.symlink(os.path.relpath(done, folder.parent), link)
        os.replace(link, folder)  # the one step that switches sets
    except BaseException as err:
        shutil.rmtree(fresh, ignore_errors=True)
        raise _as_final(err, fresh, folder) if isinstance(err, OSError) else err
    if old is not None and old.parent.resolve() == sets.resolve():  # never a foreign folder
        shutil.rmtree(old, ignore_errors=True)
    remove_stale_tmp(sets)


def remove_leaked_sets(folder) -> list[Path]:
    """Delete the finished sets of `folder` a killed process of this host never switched to."""
    folder = Path(folder)
    sets, gone = folder.parent / f".{folder.name}.sets", []
    current = set_of(folder) if folder.is_symlink() else None
    for d in sets.glob("set~*~*~*"):
        if (d.name.count("~") == 3 and d.is_dir() and not d.is_symlink()
                and d.resolve() != current and _mine_and_dead(d.name)):
            shutil.rmtree(d, ignore_errors=True)
            gone.append(d)
    return gone


def set_of(folder) -> Path:
    """The folder that holds the current set of `folder` (itself, in the old layout)."""
    return Path(folder).resolve()


# ---- a checksum over a whole record: the SHA-256 of its canonical JSON without the seal --------
SEAL = "seal"


def _encoded(record: dict) -> dict[str, str]:
    enc = _COMPACT.encode
    return {k: f"{enc(k)}:{enc(v)}" for k, v in record.items() if k != SEAL}


def _joined(items: dict[str, str]) -> str:
    return "{" + ",".join(items[k] for k in sorted(items)) + "}"


def _sha_of(items: dict[str, str]) -> str:
    return hashlib.sha256(_joined(items).encode()).hexdigest()


def sealed_json(record: dict) -> bytes:
    """The file write_json(path, seal(record), compact=True) writes, each value encoded once."""
    items = _encoded(record)
    items[SEAL] = f"{_COMPACT.encode(SEAL)}:{_COMPACT.encode(_sha_of(items))}"
    return (_joined(items) + "\n").encode()


def seal(record: dict) -> dict:
    """`record` with `seal`, the SHA-256 of everything else in it: check_seal catches any edit."""
    return {**record, SEAL: _sha_of(_encoded(record))}


def check_seal(record: dict, path=None) -> dict:
    """`record` if its seal matches its content, else DamagedFile naming `path`."""
    where = f"{path}: " if path is not None else ""
    if SEAL not in record:
        raise DamagedFile(f"{where}damaged or of an older version: no seal")
    if record[SEAL] != _sha_of(_encoded(record)):
        raise DamagedFile(f"{where}damaged: its content does not match its seal")
    return record
