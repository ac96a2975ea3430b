"""docs/cli.md is generated from the argparse definitions: it must match what the generator writes now."""

from __future__ import annotations

import argparse
from pathlib import Path

from imm_model.devtools.cli_docs import render

CLI_DOC = Path(__file__).resolve().parents[1] / "docs" / "cli.md"


def test_cli_reference_is_current():
    expected = render()
    current = CLI_DOC.read_text() if CLI_DOC.exists() else ""
    assert current == expected, (
        "docs/cli.md is stale: run `python -m imm_model.devtools.cli_docs > docs/cli.md` and commit it")


def test_cli_reference_documents_every_command_and_option():
    from imm_model.cli import build_parser
    from imm_model.devtools.cli_docs import _subcommands

    text = render()
    for name, _, sub in _subcommands(build_parser()):
        assert f"## `imm {name}`" in text
        for action in sub._actions:
            if action.option_strings and action.help != argparse.SUPPRESS and not isinstance(action, argparse._HelpAction):
                assert f"`{action.option_strings[0]}" in text, f"imm {name} {action.option_strings[0]} missing"
