"""tracker.outputs.whole_files.temporary_names: the names write_whole really writes under."""
from tracker.outputs.whole_files import temporary_names, write_whole


def test_temporary_names_are_the_names_write_whole_writes(tmp_path):
    """Through a symlink, with and without keep_suffix: the file written before the rename is
    one of temporary_names (what a script's collision check refuses as an input)."""
    (tmp_path / "real").mkdir()
    link = tmp_path / "out.png"
    link.symlink_to(tmp_path / "real" / "sheet.png")
    for keep_suffix in (False, True):
        used = []
        write_whole(link, lambda partial: (used.append(partial), partial.write_bytes(b"x")),
                    keep_suffix=keep_suffix)
        assert used == [temporary_names(link)[keep_suffix]]
    assert temporary_names(link)[1].name == "sheet.partial.png"
    assert (tmp_path / "real" / "sheet.png").read_bytes() == b"x" and link.is_symlink()
