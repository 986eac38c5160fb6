"""Write a campaign folder's ``README.md``: the command that made it, its models and its tables.

Usage (from the repository root)::

    python scripts/campaign_folder_readme.py reports/campaign-safe --commit 15351b0 [--reference mobil,sumo]

The tables are :mod:`campaign_markdown`'s from the folder's ``summary.json``; the command is
rebuilt from the folder's ``manifest.json`` (missions, planners, densities, cooperation, sublane
model, reference) with the number of seeds in ``episodes.csv``; the RSS and courtesy models are
the manifest's.  For each ``--reference`` planner the same episodes are summarised again
against it (``iamp campaign ... --no-run --reference P`` in a temporary copy of the folder,
which the folder itself never sees) and its paired table is appended.  ``--commit`` names the
commit the campaign ran from (a frozen copy of it; the manifest does not record one).
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent


def _markdown_module() -> Any:
    spec = importlib.util.spec_from_file_location("campaign_markdown", HERE / "campaign_markdown.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def command(folder: Path, man: dict[str, Any], seeds: int, out: str, workers: int = 2) -> list[str]:
    """The ``iamp campaign`` arguments that made ``folder`` (its manifest) with ``seeds`` seeds and
    ``workers`` local workers (the episodes do not depend on them)."""
    args = ["iamp", "campaign", "--missions", ",".join(man["missions"]), "--planners", ",".join(man["planners"])]
    if man.get("sublane"):
        args.append("--sublane")
    args += ["--traffic", ",".join(man["traffic"])]
    if man.get("cooperation", "default") != "default":
        args += ["--cooperation", man["cooperation"]]
    ref = json.loads((folder / "summary.json").read_text()).get("reference")
    args += ["--seeds", str(seeds)]
    if ref:
        args += ["--reference", ref]
    return args + ["--workers", str(workers), "--out", out]


def paired_lines(md: str) -> list[str]:
    """The mission headings and the paired tables of :func:`campaign_markdown.markdown`'s output."""
    keep, on = [], False
    for line in md.splitlines():
        if line.startswith("**"):
            keep.append(line)
            continue
        if line.startswith("Paired against"):
            on = True
        elif line.startswith("| planner | n |"):
            on = False
        if on:
            keep.append(line)
    return keep


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--commit", required=True)
    ap.add_argument("--workers", type=int, default=2, help="the --workers the campaign ran with")
    ap.add_argument("--reference", default="mobil,sumo", help="planners to pair against as well ('' for none)")
    ap.add_argument("--note", default="", help="a sentence after the command (e.g. a planner's episodes re-made "
                                               "on a later commit)")
    a = ap.parse_args(argv)
    folder = a.folder
    man = json.loads((folder / "manifest.json").read_text())
    with (folder / "episodes.csv").open() as fh:
        seeds = len({r["seed"] for r in csv.DictReader(fh)})
    rel = folder.as_posix()
    cmd = command(folder, man, seeds, rel, a.workers)
    cm = _markdown_module()
    rss = {k: v for k, v in man["rss"].items() if k != "source"}
    parts = [f"# SPEC §17's closed loop: {folder.name}", "",
             f"Made by `{' '.join(cmd)}` from a frozen copy of main {a.commit} on a shared 2-core machine; the "
             "command resumes, so a larger `--seeds` adds seeds. Episode format "
             f"{man.get('episode_format')}, cooperation {man.get('cooperation')}; the RSS model of the judge and of "
             f"the loop's verification: {json.dumps(rss)} ({man['rss'].get('source', '')}). "
             f"Courtesy: {json.dumps(man.get('courtesy'))}." + (f" {a.note}" if a.note else ""), "",
             f"Tables: `python scripts/campaign_markdown.py {rel}/summary.json`; this file: "
             f"`python scripts/campaign_folder_readme.py {rel} --commit {a.commit}` (the paired tables against "
             "other references summarise the same episodes with `--no-run --reference P` in a temporary copy).", "",
             cm.markdown(json.loads((folder / "summary.json").read_text()))]
    for ref in [r for r in a.reference.split(",") if r and r in man["planners"]]:
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / folder.name
            shutil.copytree(folder, copy, ignore=shutil.ignore_patterns(".iamp-lock", "README.md"))
            rerun = [sys.executable, "-m", "iamp", *command(folder, man, seeds, str(copy))[1:]]
            i = rerun.index("--reference") if "--reference" in rerun else None
            if i is not None:
                del rerun[i:i + 2]
            rerun += ["--no-run", "--reference", ref, "--quiet"]
            subprocess.run(rerun, check=True, stdout=subprocess.DEVNULL)
            md = cm.markdown(json.loads((copy / "summary.json").read_text()))
        parts += [f"## Paired against `{ref}`", "", "\n".join(paired_lines(md)), ""]
    tmp_out = folder / "README.md.tmp"
    tmp_out.write_text("\n".join(parts) + "\n")
    tmp_out.replace(folder / "README.md")
    print(f"{folder / 'README.md'}: {seeds} seeds")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
