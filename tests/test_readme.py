"""The README is a front door whose numbers come from the shipped code (issue 29 item 6, issue 31 item 5)."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def _script():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location("readme_results", ROOT / "scripts" / "readme_results.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_readme_results_are_what_the_reports_say() -> None:
    """Regenerating the block from reports/ leaves the README unchanged (run the script after a reproduce)."""
    text = README.read_text(encoding="utf-8")
    assert _script().render(text) == text


def test_the_generated_table_reads_the_reports(tmp_path: Path) -> None:
    """Not vacuous: a changed cost in results.json changes the README block."""
    import json
    import shutil

    (tmp_path / "reports").mkdir()
    results = json.loads((ROOT / "reports" / "results.json").read_text(encoding="utf-8"))
    results["safety"][0]["runs"][0]["cost"] = 1234.5
    (tmp_path / "reports" / "results.json").write_text(json.dumps(results), encoding="utf-8")
    shutil.copytree(ROOT / "reports" / "campaign-new", tmp_path / "reports" / "campaign-new")
    block = _script().block(tmp_path)
    assert "| paper-1 | 1234.500 |" in block


def test_the_readme_is_a_front_door() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    # the two commands, and the test command is the one .ci/run runs
    assert "iamp reproduce" in text
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    command = re.search(r"pip install -e '\.\[test,sim,commonroad\]' && (python -m pytest [^\n`]+)", text)
    assert command is not None
    assert command.group(1).strip() in ci
    # no machine's absolute paths
    assert not re.search(r"(/work/|/tmp/|/root/|/home/)", text)
