"""The documentation stays true to the repository: the results index is current, every result
file and relative link the README and docs/ cite exists, and the README's test command is the one
CI runs."""

from __future__ import annotations

import glob
import itertools
import re
from pathlib import Path

import pytest
from tool_scripts import load_tool

ROOT = Path(__file__).parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
RESULT_PATH = re.compile(r"benchmarks/results/[^\s`'\")\]]+")
LINK = re.compile(r"\]\(([^)\s]+)\)")


def _expanded(pattern: str) -> list[str]:
    """`a{b,c}d` -> [abd, acd]; `…`, `*` and placeholders like `<date>` become glob wildcards."""
    parts = re.split(r"\{([^}]*)\}", re.sub(r"<[^>]*>", "*", pattern))
    choices = [[p] if i % 2 == 0 else p.split(",") for i, p in enumerate(parts)]
    return ["".join(c).replace("…", "*") for c in itertools.product(*choices)]


def test_results_index_is_current():
    index = load_tool("results_index")
    assert index.INDEX.read_text() == index.index(), "run: python tools/results_index.py"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_cited_result_files_exist(doc):
    missing = []
    for cited in set(RESULT_PATH.findall(doc.read_text())):
        cited = cited.rstrip(".,;:")
        for pattern in _expanded(cited):
            if not glob.glob(str(ROOT / pattern)):
                missing.append(pattern)
    assert not missing, f"{doc.name} cites result files that do not exist: {sorted(missing)}"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_relative_links_resolve(doc):
    missing = []
    for target in LINK.findall(doc.read_text()):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue
        if not (doc.parent / target.split("#")[0]).exists():
            missing.append(target)
    assert not missing, f"{doc.name} links to paths that do not exist: {missing}"


def test_readme_test_command_is_the_one_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    assert ci in (ROOT / "README.md").read_text()


def test_readme_stays_a_short_user_guide():
    # The README is user documentation; history and diagnoses belong in docs/.
    lines = (ROOT / "README.md").read_text().count("\n")
    assert lines <= 300, f"README.md has {lines} lines; move detail to docs/"
