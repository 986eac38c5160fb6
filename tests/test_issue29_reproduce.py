"""Issue 29 items 14 and 15: ``iamp reproduce`` replaces its folder only when complete, and writes the
same bytes twice.

Item 14: the reproduction is written into a staging folder beside ``--out`` and exchanged with it
only when complete; Ctrl-C anywhere before leaves the old folder byte for byte, no staging folder,
one line ``iamp: interrupted`` and exit status 130.  Item 15: the deterministic writers (tables,
``results.json``, figures, ``report.tex``) give identical bytes when run twice, and the
machine-dependent numbers (wall times, the run time, versions) are only in ``timing/``.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from iamp.cli.main import main
from iamp.core.atomic import write_text
from iamp.core.outputs import guarded_folder

ROOT = Path(__file__).resolve().parents[1]


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``iamp argv`` in-process: ``(exit status, stdout, stderr)``."""
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def _tree(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (the lock file aside) and its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != ".iamp-lock"}


def _old_report(out: Path) -> dict[str, bytes]:
    """A folder of an earlier ``iamp reproduce`` with another command's outputs inside."""
    with guarded_folder(out, "reproduce"):
        write_text(out / "report.tex", "old report\n")
        write_text(out / "tables" / "results.tex", "old table\n")
        (out / "report.pdf").write_bytes(b"%PDF-1.5 old")
        write_text(out / "campaign-new" / "README.md", "the published campaign\n")
    return _tree(out)


def _fake_reproduce(interrupt: bool):  # type: ignore[no-untyped-def]
    def fake(out_dir, progress=None, *, status=None, quick=False, config=None):  # type: ignore[no-untyped-def]
        write_text(Path(out_dir) / "report.tex", "new report\n")
        write_text(Path(out_dir) / "tables" / "results.tex", "new table\n")
        if interrupt:
            raise KeyboardInterrupt  # Ctrl-C half-way: two files new, the rest not yet
        write_text(Path(out_dir) / "figures" / "J.png", "new figure\n")
        return {"outputs": ["report.tex", "tables/results.tex", "figures/J.png"], "notes": [], "qualitative": {}}
    return fake


def test_item14_ctrl_c_midway_leaves_the_old_folder_and_one_line(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    before = _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=True))
    code, stdout, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 130
    assert err == "iamp: interrupted\n" and stdout == ""
    assert _tree(out) == before  # not half old, half new
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]  # no staging folder left


def test_item14_a_complete_run_replaces_the_folder_and_keeps_other_outputs(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    before = _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, stdout, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    after = _tree(out)
    assert after["report.tex"] == b"new report\n" and after["tables/results.tex"] == b"new table\n"
    assert after["figures/J.png"] == b"new figure\n"
    # what this run does not write stays: another command's folder, the earlier PDF (said so)
    assert after["campaign-new/README.md"] == before["campaign-new/README.md"]
    assert after["report.pdf"] == before["report.pdf"]
    assert after[".iamp-output"] == before[".iamp-output"]
    assert f"reproduction written to {out}/" in stdout and "iamp-staging" not in stdout + err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_item14_the_exchange_without_renameat2_also_completes(tmp_path, capsys, monkeypatch):
    import iamp.cli.report as cli_report
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    _old_report(out)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    monkeypatch.setattr(cli_report, "_renameat2_exchange", lambda a, b: False)
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert (out / "report.tex").read_text() == "new report\n"
    assert (out / "campaign-new" / "README.md").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reports"]


def test_item14_ownership_and_force_are_unchanged(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    papers = tmp_path / "papers"
    papers.mkdir()
    (papers / "mine.txt").write_text("the user's")
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, _, err = run_main(["reproduce", "--out", str(papers), "--no-pdf", "--quiet"], capsys)
    assert code == 2 and "--force" in err and err.count("\n") == 1
    assert sorted(p.name for p in papers.iterdir()) == ["mine.txt"]
    code, _, err = run_main(["reproduce", "--out", str(papers), "--no-pdf", "--quiet", "--force"], capsys)
    assert code == 0, err
    assert (papers / "mine.txt").read_text() == "the user's" and (papers / "report.tex").is_file()


def test_item14_a_symlinked_output_folder_stays_a_link(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    real = tmp_path / "real"
    _old_report(real)
    link = tmp_path / "reports"
    os.symlink(real, link)
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, _, err = run_main(["reproduce", "--out", str(link), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert link.is_symlink() and (real / "report.tex").read_text() == "new report\n"


def test_item14_a_full_disk_names_the_output_not_the_staging_folder(tmp_path, capsys, monkeypatch):
    import errno

    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    before = _old_report(out)
    real_fsync = os.fsync
    state = {"armed": False}

    def fake(out_dir, progress=None, *, status=None, quick=False, config=None):  # type: ignore[no-untyped-def]
        state["armed"] = True
        write_text(Path(out_dir) / "tables" / "results.tex", "x")
        return {}

    def fsync(fd: int) -> None:
        if state["armed"]:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        real_fsync(fd)

    monkeypatch.setattr(report, "reproduce", fake)
    monkeypatch.setattr(os, "fsync", fsync)
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 2 and err.count("\n") == 1 and "No space left on device" in err
    assert str(out / "tables" / "results.tex") in err and "iamp-staging" not in err
    assert _tree(out) == before


_SLOW_REPRODUCE = """
import sys, time
from pathlib import Path
import iamp.comparison.report.reproduction as report
from iamp.core.atomic import write_text

def fake(out_dir, progress=None, *, status=None, quick=False, config=None):
    write_text(Path(out_dir) / "report.tex", "new report\\n")
    Path(sys.argv[2]).write_text("half-way")
    time.sleep(120)

report.reproduce = fake
from iamp.cli.main import main
sys.exit(main(["reproduce", "--out", sys.argv[1], "--no-pdf"]))
"""


@pytest.mark.skipif(not hasattr(os, "killpg"), reason="needs process groups (POSIX)")
def test_item14_sigint_to_the_process_group_as_a_terminal_sends_it(tmp_path):
    """The real signal, sent to the whole process group as a terminal's Ctrl-C is."""
    out = tmp_path / "reports"
    before = _old_report(out)
    ready = tmp_path / "ready"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-c", _SLOW_REPRODUCE, str(out), str(ready)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 60
        while not ready.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert ready.exists(), proc.communicate(timeout=10)
        os.killpg(proc.pid, signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130
    assert stderr == "iamp: interrupted\n" and stdout == ""
    assert _tree(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ready", "reports"]


def test_item14_a_killed_runs_staging_folder_is_removed_by_the_next_run(tmp_path, capsys, monkeypatch):
    import iamp.comparison.report.reproduction as report

    out = tmp_path / "reports"
    _old_report(out)
    stale = tmp_path / ".reports.iamp-staging-abcd1234"
    (stale / "tables").mkdir(parents=True)
    (stale / "tables" / "results.tex").write_text("a SIGKILLed run's")
    other = tmp_path / ".other.iamp-staging-abcd1234"  # another folder's: not ours to delete
    other.mkdir()
    monkeypatch.setattr(report, "reproduce", _fake_reproduce(interrupt=False))
    code, _, err = run_main(["reproduce", "--out", str(out), "--no-pdf", "--quiet"], capsys)
    assert code == 0, err
    assert not stale.exists() and other.exists()


def test_item14_the_small_campaigns_workers_ignore_ctrl_c(tmp_path, monkeypatch):
    """The workers get a preload that ignores SIGINT (a terminal sends it to the whole process group;
    each worker printed tornado/asyncio tracebacks)."""
    pytest.importorskip("dask")
    pytest.importorskip("distributed")
    import dask

    import iamp.comparison.report.campaign as campaign
    import iamp.simulation.campaign as sim_campaign
    import iamp.simulation.network as network

    seen: dict[str, object] = {}

    def fake_run_campaign(*args, **kwargs):  # type: ignore[no-untyped-def]
        seen["preload"] = list(dask.config.get("distributed.worker.preload", default=[]))
        raise KeyboardInterrupt

    monkeypatch.setattr(sim_campaign, "run_campaign", fake_run_campaign)
    monkeypatch.setattr(network, "require_sumo", lambda: None)
    (tmp_path / "tables").mkdir()
    with pytest.raises(KeyboardInterrupt):
        campaign.campaign_section(tmp_path, quick=True)
    assert campaign.PRELOAD in seen["preload"]  # type: ignore[operator]
    assert campaign.PRELOAD not in (dask.config.get("distributed.worker.preload", default=[]) or [])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tables"]  # its temporary folder removed
    # the preload, in a process of its own: SIGINT no longer raises KeyboardInterrupt
    code = ("import os, signal, time\n"
            "from iamp.comparison.report.campaign import dask_setup\n"
            "dask_setup(None)\n"
            "os.kill(os.getpid(), signal.SIGINT)\n"
            "time.sleep(0.2)\n"
            "print('still running')\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0 and proc.stdout == "still running\n", proc.stderr


_CAMPAIGN_SECTION = """
import sys
from pathlib import Path
if __name__ == "__main__":
    from iamp.comparison.report.campaign import campaign_section
    def progress(done, total):
        Path(sys.argv[2]).write_text(str(done))
    try:
        campaign_section(Path(sys.argv[1]), quick=True, progress=progress)
    except KeyboardInterrupt:
        sys.stderr.write("iamp: interrupted\\n")
        sys.exit(130)
"""


@pytest.mark.slow
def test_item14_ctrl_c_during_the_real_small_campaign_prints_no_library_traceback(tmp_path):
    """The real small campaign (SUMO, a Dask cluster of 2 worker processes), SIGINT to the process
    group while episodes run: one line, no traceback from any library (about a minute)."""
    pytest.importorskip("distributed")
    from iamp.core.errors import MissingDependencyError
    from iamp.simulation.network import require_sumo

    try:
        require_sumo()
    except MissingDependencyError as exc:
        pytest.skip(str(exc))
    script = tmp_path / "section.py"
    script.write_text(_CAMPAIGN_SECTION)
    out, ready = tmp_path / "out", tmp_path / "ready"
    (out / "tables").mkdir(parents=True)
    proc = subprocess.Popen([sys.executable, str(script), str(out), str(ready)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, cwd=str(tmp_path),
                            env={**os.environ, "PYTHONPATH": str(ROOT)},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not ready.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        time.sleep(20)  # the cluster is up and the workers are in their episodes
        os.killpg(proc.pid, signal.SIGINT)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, stderr[-3000:]
    assert stderr == "iamp: interrupted\n", stderr[-3000:]
