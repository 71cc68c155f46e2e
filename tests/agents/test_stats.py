"""agents.stats (IQM, rliable's stratified bootstrap) and ``spinstrike baselines`` end to end on a
tiny budget: the table has IQM [CI] beside mean +/- std, the plot is written, and a rerun keeps
the notes written by hand around the generated part."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from spinstrike.agents.baselines import BEGIN, END, write_doc
from spinstrike.agents.cli import main
from spinstrike.agents.stats import curve_bands, interval, iqm, summary


def test_iqm_is_the_mean_of_the_middle_half():
    assert iqm([0, 1, 2, 3, 4, 5, 6, 100]) == pytest.approx(np.mean([2, 3, 4, 5]))
    assert iqm([[1.0], [1.0]]) == 1.0
    with pytest.raises(ValueError, match="scores"):
        iqm([])


def test_interval_brackets_the_iqm_and_is_reproducible():
    rng = np.random.default_rng(0)
    scores = rng.normal(0.9, 0.05, (10, 3))
    value, low, high = interval(scores)
    assert low < value < high
    assert value == pytest.approx(iqm(scores))
    assert interval(scores) == (value, low, high)  # seeded
    # more runs, narrower interval
    wide = interval(scores[:4])
    assert (wide[2] - wide[1]) > (high - low)
    with pytest.raises(ValueError, match="shape"):
        interval(np.zeros((2, 2, 2)))
    with pytest.raises(ValueError, match="finite"):
        interval([1.0, np.nan])


def test_summary_and_bands():
    s = summary([0.5, 0.9, 0.95, 0.97, 0.99])
    assert s["runs"] == 5 and s["mean"] == pytest.approx(0.862)
    assert s["iqm_low"] <= s["iqm"] <= s["iqm_high"]
    mid, low, high = curve_bands(np.array([[0.1, 0.5, 0.9], [0.2, 0.6, 0.8], [0.0, 0.4, 1.0]]))
    assert mid.shape == (3,) and np.all(low <= mid) and np.all(mid <= high)


def test_cli_baselines_writes_iqm_table_and_curves_on_fixed_episodes(tmp_path, capsys,
                                                                     monkeypatch):
    root, doc = tmp_path / "runs", tmp_path / "docs" / "baselines.md"
    assert main(["baselines", "--quick", "--envs", "SpinStrike/PuckSpeed-v1", "--algos", "ppo",
                 "--seeds", "0", "--no-transfer", "--root", str(root), "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert "| policy | IQM [95% CI] | mean +/- std | IQM / reference |" in text
    assert "| PPO | " in text and "| oracle (closed form) | - | 1.000 +/- 0.000 | 1.000 |" in text
    assert (doc.parent / "baselines" / "PuckSpeed-v1.png").stat().st_size > 1000
    # --reuse-only trains nothing: the finished PPO run is reported, SAC is said not to be run
    doc.unlink()
    assert main(["baselines", "--reuse-only", "--quick", "--envs", "SpinStrike/PuckSpeed-v1",
                 "--algos", "ppo", "sac", "--seeds", "0", "1", "--no-transfer", "--root",
                 str(root), "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert "| SAC | not run in this budget |" in text
    assert "| PPO | " in text and " | 1 | " in text
    assert sorted(p.name for p in root.iterdir()) == ["ppo-PuckSpeed-v1-s0"]
    # notes written by hand around the generated part survive a rerun; the tables are replaced
    stale = text.replace("| SAC | not run in this budget |", "| SAC | stale |")
    edited = "Intro by hand.\n\n" + stale + "\n## Why (by hand)\n\nAn analysis.\n"
    doc.write_text(edited)
    assert main(["baselines", "--reuse-only", "--quick", "--envs", "SpinStrike/PuckSpeed-v1",
                 "--algos", "ppo", "sac", "--seeds", "0", "1", "--no-transfer", "--root",
                 str(root), "--doc", str(doc)]) == 0
    again = doc.read_text()
    assert again.startswith("Intro by hand.\n\n" + BEGIN) and "| SAC | stale |" not in again
    assert again.endswith(END + "\n\n## Why (by hand)\n\nAn analysis.\n")
    assert again.count("| SAC | not run in this budget |") == 1
    # --re-evaluate scores the finished run again (the model as it is) with the current code
    result = root / "ppo-PuckSpeed-v1-s0" / "baseline.json"
    kept = json.loads(result.read_text())
    result.write_text(json.dumps({**kept, "mean": 999.0}))
    reuse = ["baselines", "--reuse-only", "--quick", "--envs", "SpinStrike/PuckSpeed-v1",
             "--algos", "ppo", "--seeds", "0", "--no-transfer", "--root", str(root),
             "--doc", str(doc)]
    assert main(reuse) == 0 and "999.000" in doc.read_text()
    assert main([*reuse, "--re-evaluate"]) == 0 and "999.000" not in doc.read_text()
    scored = json.loads(result.read_text())
    assert scored["mean"] == kept["mean"] and scored["returns"] == kept["returns"]
    assert scored["timesteps"] == kept["timesteps"] and scored["evaluated_at"]
    # the header says other jobs shared the cores only when the load average says so
    for load, shared in ((0.1, False), (2.0, True)):
        monkeypatch.setattr(os, "getloadavg", lambda x=load: (x, x, x))
        assert main(reuse) == 0
        assert f"load average at start {load:.2f}" in doc.read_text()
        assert ("other jobs shared the cores" in doc.read_text()) is shared
    # a full report never reuses a --quick run (a tenth of the budget) as if it were a full one
    with pytest.raises(SystemExit, match=r"scaled by 0\.1, this report asks for 1\.0"):
        main([r for r in reuse if r != "--quick"])
    # a --quick run left to its defaults writes beside its runs, not over docs/baselines.md
    user = tmp_path / "user"
    user.mkdir()
    monkeypatch.chdir(user)
    assert main(["baselines", "--quick", "--reuse-only", "--envs", "SpinStrike/PuckSpeed-v1",
                 "--algos", "ppo", "--no-transfer"]) == 0
    assert (user / "runs" / "baselines-quick" / "baselines.md").is_file()
    assert not (user / "docs").exists()
    # the commit recorded is the code's, not that of a repository the command runs in
    from spinstrike.agents import baselines

    code = subprocess.run(["git", "-C", str(Path(baselines.__file__).parent), "rev-parse",
                           "--short", "HEAD"], capture_output=True, text=True)
    if code.returncode == 0:  # a checkout (an installed wheel records "unknown")
        git = ["git", "-c", "user.email=u@x", "-c", "user.name=u"]
        subprocess.run([*git, "init", "-q"], cwd=user, check=True)
        subprocess.run([*git, "commit", "-q", "--allow-empty", "-m", "theirs"], cwd=user,
                       check=True)
        assert main(["baselines", "--quick", "--reuse-only", "--envs", "SpinStrike/PuckSpeed-v1",
                     "--algos", "ppo", "--no-transfer"]) == 0
        text = (user / "runs" / "baselines-quick" / "baselines.md").read_text()
        assert f"Code at commit {code.stdout.strip()}." in text


def test_baselines_doc_markers(tmp_path):
    """The shipped ``docs/baselines.md`` has its notes outside the markers (a rerun keeps its
    analysis of the control envs); a file with one marker is refused, not overwritten."""
    shipped = (Path(__file__).resolve().parents[2] / "docs" / "baselines.md").read_text()
    doc = tmp_path / "baselines.md"
    doc.write_text(shipped)
    write_doc(doc, "# Baselines\n\nnew tables")
    text = doc.read_text()
    assert "new tables" in text and "## SpinStrike/RodSpin-v0" not in text
    assert "## Control envs: what limits the learners (issue 16)" in text
    assert "### Fourth session (2026-11-23): why the RodSpinControl students fail" in text
    # a file of the user's own, without markers, was replaced whole by --doc
    doc.write_text("my notes\n")
    with pytest.raises(SystemExit, match="has text but no markers of a generated part"):
        write_doc(doc, "tables")
    assert doc.read_text() == "my notes\n"
    doc.write_text("")  # an empty file is written
    write_doc(doc, "tables")
    assert "tables" in doc.read_text()
    doc.write_text(f"{BEGIN}\n# Baselines\nnotes with no end marker\n")
    with pytest.raises(SystemExit, match="expected the markers"):
        write_doc(doc, "tables")
    assert "notes with no end marker" in doc.read_text()


def test_cli_baselines_imitate_row(tmp_path, capsys):
    """``--imitate planner`` trains PPO started by DAgger beside plain PPO on a control env (a
    row of its own, with DAgger's wall time, and its learning curve), and ``--reuse-only``
    reports it again without training."""
    root, doc = tmp_path / "runs", tmp_path / "baselines.md"
    args = ["baselines", "--quick", "--envs", "SpinStrike/PuckSpeedControl-v0", "--algos", "ppo",
            "--imitate", "planner", "--seeds", "0", "--no-transfer", "--planner-episodes", "0",
            "--root", str(root), "--doc", str(doc)]
    assert main(args) == 0
    rows = [r for r in doc.read_text().splitlines() if r.startswith("| PPO")]
    assert len(rows) == 2 and rows[1].startswith("| PPO from the planner (DAgger) | ")
    assert " s DAgger + " in rows[1]
    run = root / "ppo-PuckSpeedControl-v0-imitate-planner-s0"
    assert (run / "imitation.csv").read_text().count("\n") == 3  # header, 2 quick rounds
    first = doc.read_text()
    assert main([*args, "--reuse-only"]) == 0
    again = [r for r in doc.read_text().splitlines() if r.startswith("| PPO")]
    assert again == rows  # same runs, same seeds' scores: the same rows
    assert first.count("PPO from the planner") == 1
    capsys.readouterr()
    assert main([*args, "--imitate", "nobody"]) == 2  # before anything is trained
    assert "unknown teacher 'nobody'" in capsys.readouterr().err
    strike = ["baselines", "--envs", "SpinStrike/RodSpin-v0", "--imitate", "planner", "--root",
              str(tmp_path / "other"), "--doc", str(tmp_path / "other.md")]
    assert main(strike) == 2 and "control envs only" in capsys.readouterr().err
    assert not (tmp_path / "other").exists() and not (tmp_path / "other.md").exists()
