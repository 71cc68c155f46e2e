"""Every command the README and ``docs/*.md`` show a user (``spinstrike ...`` and ``python -m
spinstrike...``, in code spans and shell blocks) is one the command line accepts: each is parsed
by the parser that would run it (the CLI's, then a ``bench`` / ``baselines`` module's own), and
nothing runs. An option the docs name but the code renamed or dropped fails here with
argparse's own message.

Placeholders stay as the docs write them (``RUN``, ``ID``): they are strings to the parser, so
what is checked is the options and their values' types, not that the run or env exists.
"""

from __future__ import annotations

import argparse
import importlib
import re
import shlex
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _shell_commands(block: str) -> list[str]:
    """The commands of a shell block: continuation lines joined, comments dropped, split at
    ``&&``, ``;`` and pipes."""
    text = re.sub(r"\\\n\s*", " ", block)
    out = []
    for line in text.splitlines():
        line = line.split(" #", 1)[0].strip()
        if line.startswith("#"):
            continue
        out += [part.strip() for part in re.split(r"&&|;|\|", line) if part.strip()]
    return out


def _commands(text: str) -> list[str]:
    # fences may be indented (inside a list item)
    fenced = re.findall(r"^ *```(?:bash|sh|console|shell)\n(.*?)^ *```", text, flags=re.S | re.M)
    prose = re.sub(r"^ *```.*?^ *```", "", text, flags=re.S | re.M)
    found = [c for block in fenced for c in _shell_commands(block)]
    for span in re.findall(r"`([^`]+)`", prose):
        span = " ".join(span.split())  # a code span may wrap across lines
        if "..." in span or " | " in span:  # an ellipsis or a list of alternatives, not a command
            continue
        found.append(re.sub(r"\[([^\]]*)\]", r"\1", span))  # `cache [--clear]`: the option
    return [c for c in found if re.match(r"(spinstrike|python -m spinstrike(\.\w+)*)( |$)", c)
            and c != "spinstrike"]


def _cases():
    seen: dict[str, str] = {}
    for path in DOCS:
        for command in _commands(path.read_text()):
            seen.setdefault(command, path.name)
    return [pytest.param(c, id=f"{where}: {c[:70]}") for c, where in seen.items()]


class _Parsed(Exception):
    """Raised by the patched parser once a command line parsed: nothing after it runs."""


def test_the_docs_show_commands():
    commands = [case.values[0] for case in _cases()]
    assert len(commands) >= 30, commands
    for expected in ("spinstrike train --algo ppo --env SpinStrike/RodSpin-v0",
                     "python -m spinstrike.benchmarks.speed --section bodies",
                     "spinstrike bench speed", "spinstrike cache --clear"):
        assert expected in commands, commands


@pytest.mark.parametrize("command", _cases())
def test_a_command_the_docs_show_parses(command, monkeypatch, capsys):
    parse = argparse.ArgumentParser.parse_args

    def parse_only(self, args=None, namespace=None):
        parsed = parse(self, args, namespace)
        if getattr(parsed, "command", None) in ("bench", "baselines"):
            return parsed  # the CLI hands the rest to the module, whose own parser stops here
        raise _Parsed

    monkeypatch.setattr(argparse.ArgumentParser, "parse_args", parse_only)
    words = shlex.split(command)
    if words[0] == "spinstrike":
        module, argv = "spinstrike.agents.cli", words[1:]
    else:  # python -m spinstrike[.module]
        module, argv = words[2], words[3:]
        if module == "spinstrike":
            module = "spinstrike.agents.cli"
    main = importlib.import_module(module).main
    try:
        main(argv)
    except _Parsed:
        return
    except SystemExit as exc:  # --help, --version exit 0 once printed; a refused option exits 2
        error = capsys.readouterr().err.strip().splitlines()[-1:]  # argparse's last line
        assert exc.code == 0 and argv[-1:] in (["--help"], ["--version"]), f"{command!r}: {error}"
        return
    pytest.fail(f"{command!r} ran past its parser")
