"""The start-up study's section of docs/speed.md survives the speed benchmark's regeneration."""

import subprocess
import sys

from spinstrike.benchmarks import startup


def test_section_is_written_between_markers_and_replaced(tmp_path):
    page = tmp_path / "speed.md"
    page.write_text("# Speed\n\nthe benchmark's tables\n")
    rows = [dict(label="a", cpu=12.3, wall=15.0, strikes=7000.0, steps=160000.0)]
    startup.write_section(page, startup.table(rows, "first"))
    text = page.read_text()
    assert text.startswith("# Speed\n\nthe benchmark's tables\n")
    assert "| a | 12.3 | 15.0 | 7,000 | 160,000 |" in text
    rows[0]["label"] = "b"
    startup.write_section(page, startup.table(rows, "second"))
    text = page.read_text()
    assert text.count(startup.MARK_BEGIN) == 1 and "| b |" in text and "| a |" not in text
    kept = startup.keep_section(page)
    assert kept.startswith(startup.MARK_BEGIN) and kept.endswith(startup.MARK_END)
    assert "second" in kept
    assert startup.keep_section(tmp_path / "missing.md") == ""


def test_bad_arguments_are_named(tmp_path):
    empty = tmp_path / "empty"  # a tree with no spinstrike in it: the installed code would
    empty.mkdir()               # import instead and be measured under the tree's label
    for args, word in ((["--opt", "7"], "--opt"), (["--tree", "nopath"], "--tree"),
                       (["--tree", f"old={empty}"], "imports from"),
                       (["--tree", f"old={tmp_path / 'missing'}"], "--tree")):
        out = subprocess.run([sys.executable, "-m", "spinstrike.benchmarks.startup", *args,
                              "--out", str(tmp_path / "x.md")], capture_output=True, text=True,
                             cwd=tmp_path)
        assert out.returncode == 2 and word in out.stderr, out.stderr
        assert not (tmp_path / "x.md").exists()
