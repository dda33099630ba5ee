"""Every relative link in the READMEs, ARCHITECTURE.md and the docs resolves: the file or folder
exists, and an anchor (`page.md#heading`, `#heading`) names a heading of that page as GitHub
slugs it.

Links inside code spans and fenced code blocks are not links; `http(s):` and `mailto:` targets
are not checked (no network).
"""
import pathlib
import re
import unicodedata
import urllib.parse

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent
PAGES = sorted([ROOT / "README.md", ROOT / "ARCHITECTURE.md", ROOT / "python" / "README.md",
                ROOT / "deploy" / "slurm" / "README.md", *(ROOT / "docs").rglob("*.md")])

FENCE = re.compile(r"^ {0,3}(`{3,}|~{3,})")
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1")
# [text](target) and ![alt](target); the text may hold one level of brackets (an image).
INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]"
                    r"\(\s*(<[^>]*>|[^()\s]*(?:\([^()\s]*\)[^()\s]*)*)"
                    r"(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)")
REFERENCE = re.compile(r"^ {0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)")
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ID = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"", re.I)


def prose_lines(text):
    """The page's lines outside fenced code blocks."""
    fence = None
    for n, line in enumerate(text.split("\n"), 1):
        m = FENCE.match(line)
        if fence:
            if m and m.group(1)[0] == fence[0] and len(m.group(1)) >= len(fence):
                fence = None
            continue
        if m:
            fence = m.group(1)
            continue
        yield n, line


def slug(heading):
    """GitHub's anchor for a heading: the text as rendered (no markup, a link's text alone),
    lower-cased, punctuation but hyphens and underscores dropped, spaces as hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = re.sub(r"<[^>]+>", "", text)
    text = text.replace("`", "").replace("*", "")
    out = []
    for ch in text.lower():
        cat = unicodedata.category(ch)
        if ch in " -" or ch == "_" or cat[0] in "LN" or cat[0] == "M":
            out.append("-" if ch == " " else ch)
    return "".join(out)


_anchors = {}


def anchors(page):
    """Every anchor a page has: its headings' slugs (repeats numbered as GitHub does) and
    explicit `<a name/id>`s."""
    if page not in _anchors:
        found, seen = set(), {}
        for _, line in prose_lines(page.read_text(encoding="utf-8")):
            m = HEADING.match(line)
            if m:
                s = slug(m.group(2))
                k = seen.get(s, 0)
                seen[s] = k + 1
                found.add(s if k == 0 else f"{s}-{k}")
            found.update(HTML_ID.findall(line))
        _anchors[page] = found
    return _anchors[page]


def links(page):
    """(line, target) of every link; a link's text may run over lines."""
    lines = dict(prose_lines(page.read_text(encoding="utf-8")))
    text = "\n".join(lines.get(n, "") for n in range(1, max(lines, default=0) + 1))
    text = CODE_SPAN.sub(lambda s: re.sub(r"[^\n]", " ", s.group(0)), text)
    for m in INLINE.finditer(text):
        yield text.count("\n", 0, m.start()) + 1, m.group(1).strip("<>")
    for n, line in enumerate(text.split("\n"), 1):
        m = REFERENCE.match(line)
        if m:
            yield n, m.group(1).strip("<>")


def broken(page):
    for n, target in links(page):
        if not target or re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):
            continue
        path, _, anchor = target.partition("#")
        path = urllib.parse.unquote(path)
        dest = (page.parent / path).resolve() if path else page
        where = f"{page.relative_to(ROOT)}:{n}: {target}"
        if not dest.exists():
            yield f"{where}: no such file"
        elif anchor and dest.suffix == ".md":
            if urllib.parse.unquote(anchor).lower() not in anchors(dest):
                yield f"{where}: no heading '#{anchor}' in {dest.relative_to(ROOT)}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    bad = list(broken(page))
    assert not bad, "\n".join(bad)


def test_slugs_follow_github():
    assert slug("1. A simulated hour of the 2 × 20, by numerics") == \
        "1-a-simulated-hour-of-the-2--20-by-numerics"
    assert slug("The contact law: `numerics.contact_law`") == "the-contact-law-numericscontact_law"
    assert slug("ε_CG at the consistent step") == "ε_cg-at-the-consistent-step"
    assert slug("The 0.5 s volume failure") == "the-05-s-volume-failure"
