"""The README and the pages under docs/ point at each other correctly, and the manual pages
name no commit.

* A reference to a numbered section, ``docs/X.md §N`` (also ``X.md (§N``, ``§N and §M``,
  ``§N–M``), must find a heading numbered N in X.md; a bare ``§N`` is a section of the page
  it is on.
* A reference to a heading by its title, ``X.md, "Title"``, must find a heading of X.md, or a
  paragraph's bold lead, that starts with that title.
* A link ``[text](target)`` and a bare ``X.md#anchor`` must find the file, and the anchor
  (GitHub's rule: the heading's text in lower case, punctuation dropped, spaces as '-') in it.
* A page named as ``docs/X.md``, ``notes/X.md`` or ``X.md`` must exist; so must a file of the
  repository named by its path (``dolfrag/…``, ``tests/…``, …) on a page outside docs/notes.
* No page outside docs/notes (the measurement logs and their history) holds a commit-looking
  hexadecimal token (7 to 40 digits with letters and digits, or any such token beside "commit",
  "checkout", "git", …).

Pure text: no DOLFINx, runs in a fraction of a second.
"""
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
MANUAL = [p for p in PAGES if DOCS / "notes" not in p.parents]


def name(path):
    return path.relative_to(ROOT).as_posix() if ROOT in path.parents else str(path)


# ---- headings and anchors ---------------------------------------------------------------

FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
NUMBER = re.compile(r"^(\d+(?:\.\d+)*)\.?\s")
LINK = re.compile(r"\[([^\]]*)\]\(([^)\s]*)\)")


def plain(text):
    """A heading's text as rendered: links by their text, no emphasis or code marks."""
    text = LINK.sub(r"\1", text)
    return re.sub(r"[*`]|(?<!\w)_|_(?!\w)", "", text).strip()


def anchor(text):
    """GitHub's anchor of a heading: lower case, punctuation dropped, each space a '-'."""
    return re.sub(r"[^\w\- ]", "", plain(text).lower()).replace(" ", "-")


def outside_fences(path):
    """The lines of a page that are not in fenced code blocks, with their numbers."""
    fenced = False
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if FENCE.match(line):
            fenced = not fenced
        elif not fenced:
            yield number, line


_headings = {}
BOLD_LEAD = re.compile(r"^\s*(?:[*-]\s+)?\*\*(.+?)\*\*")


def headings(path):
    """The plain text of each heading of a page (code blocks' comment lines are not headings)."""
    if path not in _headings:
        _headings[path] = [plain(m.group(2)) for _, line in outside_fences(path)
                           if (m := HEADING.match(line))]
    return _headings[path]


def titles(path):
    """What a quoted title can name: a heading, or a paragraph's bold lead (**Rigid laws** ...)."""
    return headings(path) + [plain(m.group(1)) for _, line in outside_fences(path)
                             if (m := BOLD_LEAD.match(line))]


def anchors(path):
    """Every anchor of a page, duplicates numbered as GitHub does (-1, -2, ...)."""
    seen, out = {}, set()
    for text in headings(path):
        a = anchor(text)
        out.add(a if a not in seen else f"{a}-{seen[a]}")
        seen[a] = seen.get(a, 0) + 1
    return out


def sections(path):
    return {m.group(1) for text in headings(path) if (m := NUMBER.match(text))}


# ---- resolving a page name ---------------------------------------------------------------

def resolve(page, target):
    """The file a reference on `page` names: relative to the page, then to docs/, then to the
    repository's root (prose says docs/bunker.md on the README and bunker.md inside docs/)."""
    for base in (page.parent, DOCS, ROOT):
        candidate = (base / target).resolve()
        if candidate.exists():
            return candidate
    return None


def line_of(text, offset):
    return text.count("\n", 0, offset) + 1


# ---- the references ----------------------------------------------------------------------

MD_NAME = r"(?<![\w/.-])((?:\.\./|\./)?[\w][\w./-]*\.md)"
SECTION_CHAIN = re.compile(
    MD_NAME + r"?[ \t\n,(]*(§\s?\d+(?:\.\d+)*(?:\s*(?:,|and|or|to|–|-)\s*§?\s?\d+(?:\.\d+)*(?![\w.]))*)")
# a clause of a standard (EN 1992-1-1 §3.1.3) is not a section of a page
STANDARD = re.compile(r"\b(?:EN|ISO|DIN|ASTM|ACI)\s?[\d.-]+(?:-\d+)*\s*$")
TITLED = re.compile(MD_NAME + r"[ \t\n]*[,(]?[ \t\n]*\"([^\"\n]{3,80})\"")
BARE_ANCHOR = re.compile(MD_NAME + r"#([\w-]+)")
REPO_PATH = re.compile(r"(?<![\w/.-])((?:dolfrag|tests|benchmarks|validation|demos|meshes)/[\w./-]*\w)")


def references(page):
    """(line, what, problem or None) for every reference on a page."""
    text = page.read_text(encoding="utf-8")
    out = []

    for m in LINK.finditer(text):
        target = m.group(2)
        if re.match(r"^[a-z]+:", target):  # http:, https:, mailto:
            continue
        path, _, frag = target.partition("#")
        where = resolve(page, path) if path else page
        problem = None
        if where is None:
            problem = f"no file {path}"
        elif frag and where.suffix == ".md" and frag not in anchors(where):
            problem = f"no heading #{frag} in {name(where)}"
        out.append((line_of(text, m.start()), m.group(0), problem))

    for m in BARE_ANCHOR.finditer(text):
        where = resolve(page, m.group(1))
        problem = (f"no file {m.group(1)}" if where is None
                   else None if m.group(2) in anchors(where) else f"no heading #{m.group(2)} in {name(where)}")
        out.append((line_of(text, m.start()), m.group(0), problem))

    for m in SECTION_CHAIN.finditer(text):
        target = m.group(1)
        if target is None and STANDARD.search(text[max(0, m.start() - 40):m.start()]):
            continue
        where = resolve(page, target) if target else page
        numbers = re.findall(r"\d+(?:\.\d+)*", m.group(2))
        if where is None:
            problem = f"no file {target}"
        else:
            missing = [n for n in numbers if n not in sections(where)]
            problem = f"no section {', '.join(missing)} in {name(where)}" if missing else None
        out.append((line_of(text, m.start()), m.group(0).strip(), problem))

    for m in TITLED.finditer(text):
        where = resolve(page, m.group(1))
        title = m.group(2).lower()
        if where is None:
            problem = f"no file {m.group(1)}"
        elif where.suffix != ".md":
            continue
        else:
            problem = (None if any(h.lower().startswith(title) for h in titles(where))
                       else f'no heading "{m.group(2)}" in {name(where)}')
        out.append((line_of(text, m.start()), m.group(0), problem))

    for m in re.finditer(MD_NAME, text):
        if resolve(page, m.group(1)) is None:
            out.append((line_of(text, m.start()), m.group(1), f"no page {m.group(1)}"))

    if page in MANUAL:
        for m in REPO_PATH.finditer(text):
            path = m.group(1).split("::")[0]
            if "<" in path or "*" in path:
                continue
            if not (ROOT / path).exists():
                out.append((line_of(text, m.start()), path, f"no file {path} in the repository"))
    return out


@pytest.mark.parametrize("page", PAGES, ids=name)
def test_every_reference_resolves(page):
    broken = [f"{name(page)}:{line}: {what!r}: {problem}" for line, what, problem in references(page) if problem]
    assert not broken, "\n".join(broken)


# ---- commits -----------------------------------------------------------------------------

HEX = re.compile(r"(?<![\w./-])(?<!\d,)[0-9a-f]{7,40}(?![\w./-])(?!,\d)")
GIT_WORDS = re.compile(r"\b(commit|commits|checkout|git|revision|worktree|sha|hash|PYTHONPATH|HEAD)\b",
                       re.IGNORECASE)


def commit_tokens(text):
    """Hexadecimal tokens that look like a commit: letters and digits mixed, or any beside a
    word of git's."""
    found = []
    for m in HEX.finditer(text):
        token = m.group(0)
        mixed = re.search(r"[a-f]", token) and re.search(r"\d", token)
        near = GIT_WORDS.search(text[max(0, m.start() - 80):m.end() + 80])
        if mixed or near:
            found.append((line_of(text, m.start()), token))
    return found


@pytest.mark.parametrize("text, expected", [
    ("git checkout bcedc20 && dolfrag run", ["bcedc20"]),
    ("the numpy code (commit 49b2be6)", ["49b2be6"]),
    ("on commit 1234567 of main", ["1234567"]),
    ("PYTHONPATH=<checkout of 0a785b0a785b0a785b0a785b0a785b0a785b0a78>", ["0a785b0a785b0a785b0a785b0a785b0a785b0a78"]),
    ("Ritz, 0.0012653 q a⁴/D on a square", []),
    ("1,167,137 tetrahedra, --production-cells 1167137", []),
    ("the case was accepted and effaced", []),
])
def test_the_commit_detector(text, expected):
    assert [token for _, token in commit_tokens(text)] == expected


@pytest.mark.parametrize("page", MANUAL, ids=name)
def test_no_commit_outside_the_notes(page):
    found = commit_tokens(page.read_text(encoding="utf-8"))
    assert not found, "\n".join(f"{name(page)}:{line}: {token} (commits are named in docs/notes only)"
                                for line, token in found)


def test_the_anchor_rule():
    assert anchor("Mesh convergence of the structures (`validation/convergence.py`): first meshes") \
        == "mesh-convergence-of-the-structures-validationconvergencepy-first-meshes"
    assert anchor("Hydrogen–air explosion computed from the mixture") \
        == "hydrogenair-explosion-computed-from-the-mixture"
    assert anchor("8. Outputs") == "8-outputs"
