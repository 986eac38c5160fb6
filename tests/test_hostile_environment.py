"""Bad input and a hostile environment found by fuzzing the command line (session of
2026-11-30): each is one line naming the file, option or stream, exit status 2, and nothing the
user has is replaced."""

from __future__ import annotations

import errno
import gzip
import io
import os
import subprocess
import sys
from pathlib import Path

import pytest

from iamp.cli.main import main

FIXTURES = Path(__file__).parent / "fixtures"


def _one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert "internal error" not in lines[0] and "Traceback" not in err
    return lines[0]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes on this platform")
def test_an_output_that_is_a_named_pipe_is_refused_and_kept(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """``--csv PIPE --force``: the atomic rename would replace the pipe (a device, e.g. ``/dev/null`` as
    root, likewise) by a regular file; refused, the pipe stays a pipe."""
    monkeypatch.chdir(tmp_path)
    os.mkfifo("pipe")
    assert main(["plan", "paper-1-poly", "--csv", "pipe", "--force"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "pipe" in line and "not a regular file" in line
    import stat

    assert stat.S_ISFIFO(os.stat("pipe").st_mode)


def test_a_truncated_gzip_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A valid NGSIM CSV gzipped and cut short (and one whose compressed data is corrupt): exit 2
    naming the file, not ``EOFError`` / ``zlib.error`` as an internal error."""
    data = gzip.compress((FIXTURES / "ngsim.csv").read_bytes())
    cut = tmp_path / "cut.csv.gz"
    cut.write_bytes(data[: len(data) // 2])
    bad = tmp_path / "bad.csv.gz"
    bad.write_bytes(data[:30] + b"garbage" * 20)
    for f in (cut, bad):
        assert main(["train", str(f), "--format", "ngsim", "--out", str(tmp_path / "m.json")]) == 2
        assert f.name in _one_line(capsys.readouterr().err)
    assert not (tmp_path / "m.json").exists()


@pytest.mark.parametrize("opts", [["--bins", "100000000"], ["--bin-width", "0.001", "--a-max", "50"],
                                  ["--bins", ",".join(str(k) for k in range(2000))]])
def test_more_acceleration_bins_than_the_bound_are_refused_before_any_work(
        opts: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """10^8 bins asked numpy for 284 PiB after 47 s; now refused at once naming the option."""
    from iamp.cli.prediction import MAX_BINS

    assert main(["train", str(FIXTURES / "ngsim.csv"), "--format", "ngsim", "--out", str(tmp_path / "m.json"),
                 *opts]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "--bin" in line and str(MAX_BINS) in line


class _FullStream(io.StringIO):
    def write(self, s: str) -> int:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_a_full_standard_output_is_named(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    """``iamp template > /dev/full``: the reason names the standard output."""
    monkeypatch.setattr(sys, "stdout", _FullStream())
    assert main(["template"]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "standard output" in line and os.strerror(errno.ENOSPC) in line


def test_a_removed_working_directory_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    assert main(["plan", "paper-1-poly", "--csv", "o.csv"]) == 2
    assert "working directory" in _one_line(capsys.readouterr().err)


def test_an_ascii_only_terminal_gets_the_summary_with_placeholders() -> None:
    """``PYTHONIOENCODING=ascii``: the text summary's ``Φ`` and ``²`` became a UnicodeEncodeError
    (an internal error); now they print as ``?`` and the command succeeds."""
    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    r = subprocess.run([sys.executable, "-m", "iamp", "plan", "paper-1-poly"], capture_output=True, env=env,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert b"status    optimal" in r.stdout and b"?" in r.stdout
    r.stdout.decode("ascii")  # nothing but ASCII was written


def test_location_on_a_file_without_a_location_column_is_noted(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``--location`` filters a file with a Location column; on one without it the rows are labelled
    with it (documented), and the report now says so instead of keeping every row silently."""
    import csv

    rows = list(csv.reader((FIXTURES / "ngsim.csv").read_text().splitlines()))
    loc = rows[0].index("Location")
    plain = tmp_path / "plain.csv"
    plain.write_text("\n".join(",".join(r[:loc] + r[loc + 1:]) for r in rows) + "\n")
    assert main(["train", str(plain), "--format", "ngsim", "--location", "i-80", "--out",
                 str(tmp_path / "m.json")]) == 0
    out = capsys.readouterr().out
    assert "no Location column" in out and "'i-80'" in out


def test_an_empty_output_name_is_named_as_empty(capsys: pytest.CaptureFixture[str]) -> None:
    """``--csv ''`` was "is a folder" (``Path('')`` is the working directory)."""
    assert main(["plan", "paper-1-poly", "--csv", ""]) == 2
    line = _one_line(capsys.readouterr().err)
    assert "--csv" in line and "empty" in line
