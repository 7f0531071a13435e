"""The compiled kernels' cache follows their sources (dolfrag/kernel_cache.py)."""
import os
import subprocess
import sys
import textwrap

import numba

import dolfrag
from dolfrag import kernel_cache

CALLEE = "from numba import njit\n\n\n@njit(cache=True)\ndef f():\n    return {}\n"
CALLER = "from numba import njit\n\nfrom pkg.callee import f\n\n\n@njit(cache=True)\ndef g():\n    return f()\n"


def _package(root, answer):
    pkg = root / "pkg"
    pkg.mkdir(exist_ok=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "callee.py").write_text(CALLEE.format(answer))
    (pkg / "caller.py").write_text(CALLER)
    (pkg / "other.py").write_text("X = 1\n")
    return pkg


def _g(root, cache_dir):
    """g() of root/pkg in a new process, numba's cache in ``cache_dir`` ({digest}: the package's)."""
    script = textwrap.dedent(f"""
        import importlib.util, os, sys
        from pathlib import Path
        spec = importlib.util.spec_from_file_location("kernel_cache", {kernel_cache.__file__!r})
        kernel_cache = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(kernel_cache)  # alone: without importing dolfrag and numba first
        os.environ["NUMBA_CACHE_DIR"] = {cache_dir!r}.format(digest=kernel_cache.digest(Path({str(root / 'pkg')!r})))
        sys.path.insert(0, {str(root)!r})
        from pkg.caller import g
        print(g())
    """)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, check=True)
    return int(done.stdout.split()[-1])


def test_the_digest_follows_the_kernels_and_the_modules_they_import(tmp_path):
    pkg = _package(tmp_path, 1)
    first = kernel_cache.digest(pkg)
    (pkg / "other.py").write_text("X = 2\n")  # imported by no kernel
    assert kernel_cache.digest(pkg) == first
    (pkg / "callee.py").write_text(CALLEE.format(2))
    assert kernel_cache.digest(pkg) != first
    assert [p.name for p in kernel_cache.sources(pkg)] == ["callee.py", "caller.py"]


def test_a_kernel_sees_its_changed_callee(tmp_path):
    """numba alone keeps g's compiled copy of f after f's module changes (the control below);
    the cache directory per digest compiles g afresh."""
    _package(tmp_path, 1)
    fixed, versioned = str(tmp_path / "fixed"), str(tmp_path / "versioned" / "{digest}")
    assert _g(tmp_path, fixed) == 1 and _g(tmp_path, versioned) == 1
    (tmp_path / "pkg" / "callee.py").write_text(CALLEE.format(2))
    assert _g(tmp_path, versioned) == 2
    assert _g(tmp_path, fixed) == 1  # numba alone (0.68.1): the stale callee, what kernel_cache is for


def test_dolfrag_points_numba_at_its_versioned_directory():
    assert numba.config.CACHE_DIR == os.environ["NUMBA_CACHE_DIR"] == kernel_cache.cache_directory()
    assert os.path.basename(numba.config.CACHE_DIR) == kernel_cache.digest()
    assert dolfrag.kernel_cache is kernel_cache
