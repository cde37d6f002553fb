"""The repository holds the product, not a lab notebook (issue 78 item 11).

Raw run logs (JSON lines, one per episode, stage or evaluation) stay out of git: the pages
keep the figures of the runs they quote as compact tables under docs/results/<topic>/, which
name each run by its log, and git history keeps the logs (docs/results/README.md says at which
commit). So no log is tracked, every docs/results path a page names is there, and every log
a page names is a row of a table.
"""

from __future__ import annotations

import csv
import fnmatch
import re
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
RESULTS = REPO / "docs" / "results"
#: A training run folder's own logs, which docs/training.md describes.
RUN_FOLDER_LOGS = {"log.jsonl", "evaluations.jsonl"}
#: The commit docs/results/README.md names as the last one holding the raw logs.
HISTORY = re.compile(r"last commit that holds\s+them is `([0-9a-f]{40})`")


def _pages() -> Iterator[Path]:
    yield REPO / "README.md"
    for folder in ("docs", "sim4endor", "experiments"):
        yield from sorted((REPO / folder).rglob("*.md"))


def _git(*args: str) -> str:
    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    try:
        done = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True,
                              check=True)
    except (OSError, subprocess.CalledProcessError) as exc:
        pytest.skip(f"git {' '.join(args)} failed: {exc}")
    return done.stdout


def _expand(name: str) -> list[str]:
    """``a{b,c}d`` as ``abd``, ``acd`` (the pages' shorthand for sibling logs)."""
    match = re.search(r"\{([^{}]*)\}", name)
    if match is None:
        return [name]
    return [expanded for option in match.group(1).split(",")
            for expanded in _expand(name[:match.start()] + option + name[match.end():])]


def _table_logs() -> set[str]:
    """The logs the tables summarise, as paths in the commit that holds them: a table's
    ``file`` column names a log of its topic's ``experiments/results/<topic>/``, or its path."""
    logs = set()
    for table in RESULTS.rglob("*.csv"):
        with table.open(newline="") as stream:
            files = {row["file"] for row in csv.DictReader(stream)}
        logs |= {f if "/" in f else f"experiments/results/{table.parent.name}/{f}" for f in files}
    return logs


def test_no_raw_run_logs_are_tracked() -> None:
    tracked = _git("ls-files", "-z").split("\0")
    logs = [path for path in tracked if path.endswith(".jsonl") and not path.startswith("tests/")]
    assert logs == [], "raw run logs belong in git history, their figures in docs/results"


def test_every_docs_results_path_a_page_names_exists() -> None:
    missing = []
    for page in _pages():
        text = page.read_text()
        links = [page.parent / target.split("#")[0] for target in
                 re.findall(r"\]\(([^)\s:]+)\)", text)]
        mentions = [REPO / path for mention in re.findall(r"docs/results/[\w./{},-]*", text)
                    for path in _expand(mention.rstrip(".,"))]
        for path in links + mentions:
            resolved = path.resolve()
            # A log named under docs/results is one git history holds (the last test).
            if (resolved.is_relative_to(RESULTS) and resolved.suffix != ".jsonl"
                    and not resolved.exists()):
                missing.append(f"{page.relative_to(REPO)}: {path}")
    assert missing == []


def test_every_log_a_page_names_is_a_row_of_a_table() -> None:
    files = {Path(log).name for log in _table_logs()}
    unlisted = []
    for page in _pages():
        for name in re.findall(r"[\w.{},*-]+\.jsonl", page.read_text()):
            if name in RUN_FOLDER_LOGS or name.startswith("..."):  # "..._3x75_7x40.jsonl"
                continue
            unlisted += [f"{page.relative_to(REPO)}: {expanded}" for expanded in _expand(name)
                         if not fnmatch.filter(files, expanded)]
    assert unlisted == []


def test_the_commit_the_docs_name_holds_the_raw_logs_and_the_tables_cover_them() -> None:
    match = HISTORY.search((RESULTS / "README.md").read_text())
    assert match, "docs/results/README.md names the commit that holds the raw logs"
    if _git("rev-parse", "--is-shallow-repository").strip() == "true":
        pytest.skip("a shallow clone may lack the commit")
    listed = _git("ls-tree", "-r", "--name-only", match.group(1), "experiments/results",
                  "docs/results").split("\n")
    assert {path for path in listed if path.endswith(".jsonl")} == _table_logs()
