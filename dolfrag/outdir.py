"""The output folder of a run: checked before anything is meshed, so that a run never
mixes its files with another's.

A folder that exists and holds anything is refused unless the user asks to overwrite it,
and then it is emptied first; a path that is a file, or a folder that cannot be written,
is refused. Nothing is created here: the run creates the folder when it writes.
"""
import os
import shutil
from pathlib import Path

from dolfrag.case import CaseError


def _writable_ancestor(path):
    """The nearest existing folder at or above ``path`` (where the run would create it)."""
    for parent in (path, *path.parents):
        if parent.exists():
            return parent
    return Path.cwd()


def check(out, overwrite=False):
    """CaseError (one line: --out, the path, what is allowed) if ``out`` is a file, cannot
    be written, or is a folder that is not empty and ``overwrite`` is False. Touches nothing."""
    path = Path(out).expanduser().absolute()
    where = f"--out = '{out}'"
    if path.exists() and not path.is_dir():
        raise CaseError(f"{where}: is a file; must be a folder, new or empty")
    parent = _writable_ancestor(path)
    if not parent.is_dir():
        raise CaseError(f"{where}: '{parent}' is a file; must be a folder that can be created")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise CaseError(f"{where}: '{parent}' is not writable; must be a folder this user can write")
    if path.is_dir() and any(path.iterdir()) and not overwrite:
        raise CaseError(f"{where}: folder is not empty; must be new or empty "
                        "(--overwrite empties it first)")


def prepare(out, overwrite, comm):
    """check(out, overwrite) on rank 0, then, if ``overwrite``, empty the folder (its
    contents, not the folder itself: it may be a mount point or a link). Collective; every
    rank raises the same CaseError."""
    error = None
    if comm.rank == 0:
        try:
            check(out, overwrite)
            path = Path(out)
            if overwrite and path.is_dir():
                for entry in path.iterdir():
                    if entry.is_dir() and not entry.is_symlink():
                        shutil.rmtree(entry)
                    else:
                        entry.unlink()
        except CaseError as err:
            error = str(err)
    error = comm.bcast(error, root=0)
    if error:
        raise CaseError(error)
