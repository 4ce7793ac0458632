"""Usage errors are one line naming the problem, for track and every script."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tracker.one_line_parser import EXIT_USAGE, OneLineParser

_SCRIPTS = sorted((Path(__file__).resolve().parents[1] / "scripts").glob("*.py"))


def test_an_unknown_option_is_one_line_with_the_usage_status(capsys):
    parser = OneLineParser(prog="tool")
    parser.add_argument("--count", type=int)
    with pytest.raises(SystemExit) as stop:
        parser.parse_args(["--count", "many"])
    assert stop.value.code == EXIT_USAGE
    err = capsys.readouterr().err
    assert err == "tool: error: argument --count: invalid int value: 'many' (see tool --help)\n"


@pytest.mark.parametrize("script", _SCRIPTS, ids=[s.stem for s in _SCRIPTS])
def test_every_script_refuses_a_bad_option_in_one_line(script, tmp_path):
    done = subprocess.run([sys.executable, str(script), "--definitely-not-an-option"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == EXIT_USAGE
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{script.name}: error: "), done.stderr


def _refused_outputs(capsys, outputs, inputs=()) -> str:
    with pytest.raises(SystemExit) as exit_:
        OneLineParser(prog="p").check_outputs(outputs, inputs)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    return err


def test_check_outputs_refuses_an_output_that_is_an_input_a_folder_or_in_no_folder(tmp_path,
                                                                                   capsys):
    model = tmp_path / "m.npz"
    model.write_bytes(b"model")
    (tmp_path / "link.npz").symlink_to(model)
    assert "same file as --model" in _refused_outputs(
        capsys, [("--json", tmp_path / "link.npz")], [("--model", model)])
    assert "is a folder" in _refused_outputs(capsys, [("--json", tmp_path)])
    assert "no folder" in _refused_outputs(capsys, [("--json", tmp_path / "none" / "a.json")])
    assert "same file as --json" in _refused_outputs(
        capsys, [("--json", tmp_path / "a.json"), ("--out", tmp_path / "a.json")])
    # Distinct, writable outputs pass; None entries are skipped.
    OneLineParser(prog="p").check_outputs([("--json", tmp_path / "a.json"), ("--x", None)],
                                          [("--model", model), ("--y", None)])
    assert model.read_bytes() == b"model"


def test_check_outputs_takes_links_special_files_and_inputs_that_are_one_another(tmp_path):
    """A symlink to a file in a writable folder, /dev/null, and two inputs that are the same
    file (a folder of links) are all fine; the output is checked where its link points."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "a.bvh").write_text("motion")
    (data / "alias.bvh").symlink_to(data / "a.bvh")
    (tmp_path / "out.json").symlink_to(tmp_path / "real.json")
    OneLineParser(prog="p").check_outputs(
        [("--json", tmp_path / "out.json"), ("--log", Path("/dev/null"))],
        [("--bvh-dir", data / "a.bvh"), ("--bvh-dir", data / "alias.bvh")])


def test_write_whole_follows_links_and_writes_special_files_in_place(tmp_path):
    from tracker.outputs.whole_files import write_whole
    real = tmp_path / "real.json"
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    write_whole(link, lambda partial: partial.write_text("new"))
    assert link.is_symlink() and real.read_text() == "new"
    write_whole(Path("/dev/null"), lambda path: path.write_text("nothing"))
    assert Path("/dev/null").is_char_device()
    png = tmp_path / "sheet.png"
    write_whole(png, lambda partial: partial.write_text(partial.suffix), keep_suffix=True)
    assert png.read_text() == ".png" and sorted(p.name for p in tmp_path.iterdir()) == [
        "link.json", "real.json", "sheet.png"]


def test_check_outputs_refuses_an_output_whose_temporary_name_is_an_input(tmp_path, capsys):
    """write_whole writes NAME.partial (or NAME.partial.png) first and keeps a file found
    there aside: an input of that name would be moved from under the script."""
    for temporary, output in (("r.json.partial", "r.json"), ("s.partial.png", "s.png")):
        data = tmp_path / temporary
        data.write_text("input")
        err = _refused_outputs(capsys, [("--json", tmp_path / output)], [("--data", data)])
        assert "is written as" in err and "--data" in err
        assert data.read_text() == "input"


def test_write_whole_to_a_pipe_writes_into_it(tmp_path):
    """/dev/stdout sent to a pipe has no path to resolve: written in place (it had failed,
    naming /proc/PID/fd/pipe:[N])."""
    import os
    from tracker.outputs.whole_files import write_whole
    read, write = os.pipe()
    try:
        write_whole(f"/dev/fd/{write}", lambda path: path.write_text("through the pipe"))
    finally:
        os.close(write)
    with os.fdopen(read) as pipe:
        assert pipe.read() == "through the pipe"


def test_scripts_print_warnings_in_one_line(capsys):
    import warnings
    from tracker.one_line_parser import stops_in_one_line

    def main(argv):
        warnings.warn("a file was kept aside")
        return 0
    assert stops_in_one_line("script", main)([]) == 0
    assert capsys.readouterr().err == "script: warning: a file was kept aside\n"
