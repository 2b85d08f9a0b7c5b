"""The one overwrite rule for every file a verb writes where the user pointed it.

    claim_output(path, force=..., inputs=...)   before any work: may `path` be written?
    output_file(path, force=..., inputs=...)    a temporary sibling to write, renamed into place

The rule (README "Nothing is overwritten"): a missing target is written; an existing one is refused
(OutputError, exit 4) unless `--force`, and `--force` replaces only a file this tool wrote and
nobody changed since (its name and SHA-256 are in `.mrnc-eval-outputs.json` beside it), never an
input of a run the command reads (the log, its ground truth, the run's own files), whatever the
manifest says. `report --out`, `table --out`, `compare --out`, `ape/rpe --table/--plot`, `--junit`,
`export --mcap` and the API's result folders all go through here.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from mrnc_eval.errors import OutputError, raise_if_interrupted

MANIFEST = ".mrnc-eval-outputs.json"  # name -> sha256 of the files this tool wrote in a folder


def _umask() -> int:
    mask = os.umask(0o022)  # read it back: there is no getter
    os.umask(mask)
    return mask


def follow_umask(path: Path) -> None:
    """Give a file or folder made by mkstemp/mkdtemp (0600/0700) the mode an ordinary
    open()/mkdir() would have given it, so teammates and web servers can read reports."""
    base = 0o777 if path.is_dir() else 0o666
    os.chmod(path, base & ~_umask())


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def _manifest(folder: Path) -> dict[str, str]:
    try:
        data = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def written_by_us(path: Path) -> bool:
    """`path` is a regular file this tool wrote and nobody changed since."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return False
    digest = _manifest(path.parent).get(path.name)
    try:
        return digest is not None and digest == _sha256(path)
    except OSError:
        return False


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve() or (a.exists() and b.exists() and os.path.samefile(a, b))
    except OSError:
        return False


def _inside(path: Path, folder: Path) -> bool:
    try:
        return folder.is_dir() and path.resolve().is_relative_to(folder.resolve())
    except OSError:
        return False


def claim_output(path: str | Path, *, force: bool = False, inputs: Iterable[str | Path] = ()) -> Path:
    """Before any work: raise OutputError unless `path` may be written under the rule above.
    `inputs` are files (or folders: a ROS 2 bag, a result folder) the command reads."""
    path = Path(path)
    for inp in inputs:
        inp = Path(inp)
        if _same_file(path, inp) or _inside(path, inp):
            raise OutputError(path, f"is an input of this command ({inp}); never replaced, even with --force")
    if not path.exists() and not path.is_symlink():
        if path.parent.exists() and not path.parent.is_dir():
            raise OutputError(path.parent, "exists and is not a folder")
        return path
    if path.is_dir() and not path.is_symlink():
        raise OutputError(path, "is a folder; give a file name")
    if not force:
        raise OutputError(path, "already exists; not replaced (--force replaces a file this tool wrote)")
    if not written_by_us(path):
        raise OutputError(path, "exists and is not a file this tool wrote (or it was changed since); "
                          "not replaced, even with --force")
    return path


def record_output(path: Path) -> None:
    """Note `path` (just written) in its folder's manifest, so a later --force may replace it."""
    path = Path(path)
    entries = _manifest(path.parent)
    entries[path.name] = _sha256(path)
    entries = {k: v for k, v in entries.items() if (path.parent / k).is_file()}  # forget removed files
    fd, tmp = tempfile.mkstemp(prefix=f".{MANIFEST}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(entries, fh, indent=1, sort_keys=True)
        follow_umask(Path(tmp))
        os.replace(tmp, path.parent / MANIFEST)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def output_file(path: str | Path, *, force: bool = False, inputs: Iterable[str | Path] = ()) -> Iterator[Path]:
    """Claim `path` (the rule above), yield a temporary sibling to write, then rename it into place
    with the umask's mode and record it. On any error the target is untouched and the temporary
    file removed; an OSError names the target, not the temporary file."""
    path = claim_output(path, force=force, inputs=inputs)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=path.parent)
        os.close(fd)
    except OSError as err:
        raise OutputError(path, f"cannot write here: {describe(err)}") from err
    tmp = Path(name)
    try:
        try:
            yield tmp
            follow_umask(tmp)
            raise_if_interrupted()  # never commit an output a Ctrl-C may have cut short
            claim_output(path, force=force, inputs=inputs)  # still ours to replace (nothing appeared meanwhile)
            os.replace(tmp, path)
            record_output(path)
        except OSError as err:
            if err.filename not in (None, str(tmp), str(path), tmp, path):
                raise  # another file's error (an input read inside the block): not the output's
            raise OutputError(path, f"cannot write: {describe(err)}") from err
    finally:
        tmp.unlink(missing_ok=True)


def write_output(path: str | Path, data: str | bytes, *, force: bool = False,
                 inputs: Iterable[str | Path] = ()) -> Path:
    """Write text (UTF-8) or bytes to `path` under the rule, atomically."""
    with output_file(path, force=force, inputs=inputs) as tmp:
        if isinstance(data, str):
            tmp.write_text(data, encoding="utf-8")
        else:
            tmp.write_bytes(data)
    return Path(path)


def describe(err: OSError) -> str:
    """The system's reason for a file-system error, without the (temporary) file name."""
    import errno

    if err.errno == errno.ENOSPC:
        return "no space left on device"
    return err.strerror or type(err).__name__
