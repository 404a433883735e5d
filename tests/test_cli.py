"""The command line as a user meets it: help for every option, defaults stated, the same
options across subcommands, ``--show`` refused clearly where OpenCV has no GUI."""

from __future__ import annotations

import argparse

import pytest

from fisheyemotion.cli import build_parser, main

PARSER = build_parser()
SUBCOMMANDS = {name: sub for action in PARSER._actions
               if isinstance(action, argparse._SubParsersAction)
               for name, sub in action.choices.items()}


def options(sub: argparse.ArgumentParser):
    return [a for a in sub._actions if not isinstance(a, argparse._HelpAction)]


def test_every_subcommand_is_registered():
    assert set(SUBCOMMANDS) == {"detect", "synth", "calib", "eval", "compare", "demo"}


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_every_option_has_help_and_states_its_default(name):
    for action in options(SUBCOMMANDS[name]):
        label = action.option_strings or [action.dest]
        assert action.help and len(action.help) > 10, f"{name} {label}: no help"
        if action.option_strings and action.nargs != 0 and not action.required:
            assert "default" in action.help or "required unless" in action.help, (
                f"{name} {label}: the default is not stated")


@pytest.mark.parametrize("name", sorted(SUBCOMMANDS))
def test_help_renders_without_markup(name, capsys):
    with pytest.raises(SystemExit) as info:
        main([name, "--help"])
    text = capsys.readouterr().out
    assert info.value.code == 0
    assert "``" not in text and ":mod:" not in text and "%(default)" not in text


def test_writing_commands_share_out_overwrite_and_quiet():
    for name in ("detect", "synth", "eval", "compare"):
        flags = {s for a in options(SUBCOMMANDS[name]) for s in a.option_strings}
        assert {"--out", "--overwrite", "--quiet"} <= flags, name
    for name in ("detect", "synth", "eval", "compare", "demo"):
        flags = {s for a in options(SUBCOMMANDS[name]) for s in a.option_strings}
        assert "--quiet" in flags


def test_top_level_help_has_no_docstring_markup(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "``" not in text and ":mod:" not in text and "--version" in text


def test_show_without_a_gui_opencv_is_one_clear_error(tmp_path, capsys):
    import cv2

    if "GUI:                           NONE" not in cv2.getBuildInformation():
        pytest.skip("this OpenCV has a GUI")
    code = main(["detect", str(tmp_path), "--out", str(tmp_path / "out"), "--show"])
    err = capsys.readouterr().err
    assert code == 2 and "--show" in err and "opencv-python" in err
    assert not (tmp_path / "out").exists()
