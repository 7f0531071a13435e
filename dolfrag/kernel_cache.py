"""Where numba keeps dolfrag's compiled kernels: one directory per version of their sources.

numba's cache (``@njit(cache=True)``) checks a function against its own source file only. A
kernel that calls a compiled function of another module keeps that function's old machine
code after the other module changes: measured, the star loop (solver/stars/loop.py) went on
running a superseded star Newton (solver/stars/newton.py) through a series of edits, and
iterated differently from the source until its cache was compiled afresh. So dolfrag points
numba at a directory named after a digest of every module that holds compiled code and of the
dolfrag modules those import (whose constants numba freezes into the machine code): a change
to any of them compiles the kernels afresh, in a new directory, once. Older directories are
left where they are; deleting them is safe (``make clean``).
"""
import ast
import hashlib
import os
import re
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
COMPILED = re.compile(r"^@njit", re.MULTILINE)  # a module holding compiled code


def _module_file(root, name):
    """The file of dolfrag module ``name`` (dotted) under the package ``root``, or None."""
    parts = name.split(".")[1:]
    path = root.joinpath(*parts)
    for candidate in (path.with_suffix(".py"), path / "__init__.py"):
        if parts and candidate.is_file():
            return candidate
    return None


def _imported(root, path):
    """The files of the dolfrag modules ``path`` imports at its top level."""
    names = []
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(root.name):
            names += [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        elif isinstance(node, ast.Import):
            names += [alias.name for alias in node.names if alias.name.startswith(root.name)]
    return {f for f in (_module_file(root, n) for n in names) if f is not None}


def sources(root=PACKAGE):
    """The modules under ``root`` that hold compiled code, and the package's modules they import."""
    kernels = {p for p in root.rglob("*.py") if COMPILED.search(p.read_text())}
    return sorted(kernels.union(*(_imported(root, p) for p in kernels)))


def digest(root=PACKAGE):
    """A short digest of the names and contents of ``sources(root)``."""
    h = hashlib.sha256()
    for path in sources(root):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_directory(root=PACKAGE):
    """The kernels' cache directory for this version of their sources: under the user's
    NUMBA_CACHE_DIR if set (kept as it is when it already names this version, as in a process
    a dolfrag process started), else in the package's ``__pycache__`` (or the user's cache
    directory where the package cannot be written)."""
    version = digest(root)
    parent = os.environ.get("NUMBA_CACHE_DIR")
    if parent and Path(parent).name == version:
        return parent
    if not parent:
        parent = root / "__pycache__" / "numba" if os.access(root, os.W_OK) else \
            Path.home() / ".cache" / "dolfrag" / "numba"
    return str(Path(parent) / version)


def use_versioned_cache():
    """Point numba's cache at ``cache_directory()``. Called by ``import dolfrag``, before any
    compiled module is imported: numba picks a function's cache directory when it is decorated."""
    directory = cache_directory()
    os.environ["NUMBA_CACHE_DIR"] = directory  # also for the processes this one starts (mpirun)
    config = sys.modules.get("numba.core.config")
    if config is not None:  # numba imported first: it read NUMBA_CACHE_DIR already
        config.CACHE_DIR = directory
