"""Issue 22 ("the everyday tool, second pass"): each item's regression test.

Every test here failed on the code before its fix (the commit message of each item says how it
was measured); the item number is in each test's name.
"""

from __future__ import annotations

import pytest

from iamp.cli.main import main


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """``iamp argv`` in-process: ``(exit status, stdout, stderr)``."""
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _no_episode(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make any episode an error: a refusal must come before SUMO starts."""
    import iamp.simulation.episode as episode

    def refuse(spec: object) -> None:
        raise AssertionError("the episode ran before the destinations were checked")

    monkeypatch.setattr(episode, "run_episode", refuse)


# --- item 2: simulate --log / --figure are checked before the episode ------------------------


@pytest.mark.parametrize("option", ["--log", "--figure"])
def test_item2_simulate_refuses_an_existing_file_before_the_episode(tmp_path, capsys, monkeypatch, option):
    _no_episode(monkeypatch)
    target = tmp_path / ("old.csv" if option == "--log" else "old.png")
    target.write_text("the user's file")
    code, out, err = run_main(["simulate", "--seed", "1", option, str(target)], capsys)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and option in err and str(target) in err and "--force" in err
    assert target.read_text() == "the user's file"


def test_item2_simulate_refuses_log_and_figure_on_one_path(tmp_path, capsys, monkeypatch):
    _no_episode(monkeypatch)
    same = tmp_path / "x.png"
    code, _, err = run_main(["simulate", "--log", str(same), "--figure", str(same)], capsys)
    assert code == 2 and "--figure" in err and "--log" in err and not same.exists()


def test_item2_simulate_refuses_an_unwritable_or_unknown_destination_before_the_episode(tmp_path, capsys,
                                                                                        monkeypatch):
    _no_episode(monkeypatch)
    code, _, err = run_main(["simulate", "--figure", str(tmp_path / "f.bmpx")], capsys)
    assert code == 2 and "--figure" in err and ".png" in err
    (tmp_path / "a-file").write_text("")
    code, _, err = run_main(["simulate", "--log", str(tmp_path / "a-file" / "f.csv")], capsys)
    assert code == 2 and err.count("\n") == 1 and "--log" in err and "a-file" in err
