"""The figure studies and the examples run the default step: they set no `numerics.*` key.

A product study says only what it varies; the step is the `standard` preset's (the full-scale
files name a preset by `preset = ...`, which is not a numerics key). The fitness studies
(step-fitness*, mesh-fitness, motion-convergence) compare numerics and are left out.
"""
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent
PRODUCT_STUDIES = sorted(ROOT.glob("studies/fig*.toml")) + [ROOT / "studies/jam-day.toml"]
EXAMPLES = sorted(ROOT.glob("examples/*.toml")) + sorted(ROOT.glob("studies/specs/*.toml"))


def code(line):
    """LINE without its comment: a '#' outside a quoted string starts one."""
    quote = None
    for i, c in enumerate(line):
        if quote:
            quote = None if c == quote else quote
        elif c in "\"'":
            quote = c
        elif c == "#":
            return line[:i]
    return line


# A dotted key "numerics.x" anywhere on a line (the study files' spelling, inline tables too) or
# a [numerics] table (the spec files'). The specs' dialect (`scene = "fusion"` beside a [scene]
# table) is not TOML that tomllib reads, so lines are scanned rather than parsed.
NUMERICS = re.compile(r'(^|[\s{,])"?numerics\.[a-z_]+"?\s*=|^\s*\[\s*numerics\s*\]')


def numerics_keys(text):
    """The lines of TEXT (1-based numbers) that set a numerics key."""
    return [n for n, line in enumerate(text.splitlines(), 1) if NUMERICS.search(code(line))]


def test_the_scan_finds_numerics_keys_in_each_spelling():
    text = ('[spec]\n"numerics.dt_s" = 0.5  # numerics.cg_tol = 1\n[[grid]]\n'
            '"numerics.cg_tol" = [0.01]\nthis = { "cells.alpha" = 1, "numerics.dt_s" = 1 }\n'
            '[numerics]\ndt_s = 1.0\n')
    assert numerics_keys(text) == [2, 4, 5, 6]
    assert numerics_keys('preset = "reference"\n# "numerics.dt_s" = 0.5\nx = "numerics.cg_tol"\n'
                         'title = "a # b"  # "numerics.dt_s" = 1\n') == []


@pytest.mark.parametrize("path", PRODUCT_STUDIES + EXAMPLES, ids=lambda p: p.name)
def test_sets_no_numerics_key(path):
    assert path.exists(), path
    lines = numerics_keys(path.read_text(encoding="utf-8"))
    assert not lines, f"{path.relative_to(ROOT)} sets numerics keys (lines {lines}): product " \
        "studies and examples run the default step (docs/science/presets.md)"
