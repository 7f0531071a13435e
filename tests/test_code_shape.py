"""The shape of the package's code: no function outside the compiled kernels is longer than
MAX_LINES without saying why.

A function's length is the lines of its body after the docstring (the docstring is where
units, shapes and the reason for a length go, and is not held against it). Functions
compiled by numba (a ``njit`` or ``jit`` decorator) are exempt: a kernel keeps its loop in
one function so that the compiler sees it whole (one compiled loop over all the stars).
Any other function over MAX_LINES says why in its docstring with a sentence starting with
LONG_BECAUSE, e.g. "Long on purpose: the steps share one state that a split would pass
around in ten arguments."
"""
import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "dolfrag"
MAX_LINES = 60
LONG_BECAUSE = "Long on purpose:"
COMPILERS = {"njit", "jit"}  # numba's decorators, bare or as numba.njit(...)


def _compiled(node):
    """Whether a FunctionDef carries one of numba's COMPILERS."""
    for decorator in node.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", None)
        if name in COMPILERS:
            return True
    return False


def body_lines(node):
    """Lines of a FunctionDef's body, its docstring left out."""
    body = node.body
    if len(body) > 1 and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
            and isinstance(body[0].value.value, str):
        body = body[1:]
    return body[-1].end_lineno - body[0].lineno + 1


def _justified(node):
    """Whether the docstring gives a reason after LONG_BECAUSE (a word at least)."""
    doc = ast.get_docstring(node) or ""
    return LONG_BECAUSE in doc and bool(doc.split(LONG_BECAUSE, 1)[1].strip())


def long_functions(source, name="<source>"):
    """[(where, lines)] of the functions in ``source`` (Python text) over MAX_LINES that are
    neither compiled nor justified; where is name:line function."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not _compiled(node) \
                and body_lines(node) > MAX_LINES and not _justified(node):
            found.append((f"{name}:{node.lineno} {node.name}", body_lines(node)))
    return found


def _function(lines, decorator="", doc="A function."):
    body = "\n".join(f"    x{i} = {i}" for i in range(lines))
    return f"{decorator}\ndef f():\n    \"\"\"{doc}\"\"\"\n{body}\n"


def test_a_long_function_is_found_unless_compiled_or_justified():
    assert long_functions(_function(MAX_LINES)) == []
    assert long_functions(_function(MAX_LINES + 1)) == [("<source>:2 f", MAX_LINES + 1)]
    assert long_functions(_function(MAX_LINES + 1, "@numba.njit(cache=True)")) == []
    assert long_functions(_function(MAX_LINES + 1, "@njit")) == []
    assert long_functions(_function(MAX_LINES + 1, doc=f"A function. {LONG_BECAUSE} one table.")) == []
    assert long_functions(_function(MAX_LINES + 1, doc=f"A function. {LONG_BECAUSE}")) != []


def test_no_function_of_the_package_is_long_without_a_reason():
    found = [hit for path in sorted(PACKAGE.rglob("*.py"))
             for hit in long_functions(path.read_text(), str(path.relative_to(PACKAGE.parent)))]
    assert found == [], (f"over {MAX_LINES} lines (split them, or give the reason in the docstring "
                         f"after {LONG_BECAUSE!r}): {found}")
