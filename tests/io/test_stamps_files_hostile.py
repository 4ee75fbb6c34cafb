"""Stamps files as users and other tools write them, and as they go wrong (rig.yaml's
``stamps:``, :mod:`multieye.io.frame_stamps`): every misfit is one DatasetError naming the file
(and the line where there is one), never an OverflowError, never a stamp silently dropped or
taken from another image's line."""

from __future__ import annotations

import numpy as np
import pytest

from multieye.core.errors import DatasetError
from multieye.io.frame_stamps import MAX_STAMP_NS, read_frame_stamps, read_image_stamps


@pytest.fixture
def images(tmp_path):
    """Three images ``000000.png`` ... below ``tmp_path / 'data'``."""
    folder = tmp_path / "data"
    folder.mkdir()
    paths = [folder / f"{k:06d}.png" for k in range(3)]
    for p in paths:
        p.write_bytes(b"")
    return folder, paths


@pytest.mark.parametrize("lines, line", [
    (["1.0e300", "2.0e300", "3.0e300"], 1),                      # beyond the float range
    (["1e400", "2e400", "3e400"], 1),
    (["9300000000000000000", "9300000000000000001", "9300000000000000002"], 1),  # > int64
    (["1.0e10", "1.1e10", "1.2e10"], 1),                        # 1e19 ns: > int64
    (["9999-12-31 23:59:57", "9999-12-31 23:59:58", "9999-12-31 23:59:59"], 1),
    (["1900-01-01 00:00:00", "1900-01-01 00:00:01", "1900-01-01 00:00:02"], 1),  # before 1970
    (["1.0", "2.0", "3.0e300"], 3),
])
def test_stamps_beyond_the_bounds_are_refused_with_their_line(tmp_path, images, lines, line):
    folder, paths = images
    f = tmp_path / "stamps.txt"
    f.write_text("\n".join(lines) + "\n")
    for read in (lambda: read_frame_stamps(f), lambda: read_image_stamps(f, paths, folder)):
        with pytest.raises(DatasetError, match="from 0 \\(1970\\) to") as info:
            read()
        assert info.value.line == line, str(info.value)


def test_the_largest_stamp_is_read_exactly(tmp_path):
    f = tmp_path / "stamps.txt"
    f.write_text(f"{MAX_STAMP_NS - 1}\n{MAX_STAMP_NS}\n")
    assert read_frame_stamps(f).tolist() == [MAX_STAMP_NS - 1, MAX_STAMP_NS]


@pytest.mark.parametrize("first", ["-0.5", "nan", "inf", "1.0x", "+1.5", "1_0.0", "1.0\0"])
def test_a_first_line_that_is_a_stamp_gone_wrong_is_no_header(tmp_path, images, first):
    """One stamp per line with a bad first line and as many good lines as images: before,
    the bad line was dropped as a header and the file taken as right."""
    folder, paths = images
    f = tmp_path / "stamps.txt"
    f.write_text(f"{first}\n1.0\n2.0\n3.0\n")
    with pytest.raises(DatasetError, match="expected one time stamp per line") as info:
        read_image_stamps(f, paths, folder)
    assert info.value.line == 1


@pytest.mark.parametrize("header", ["timestamp", "timestamp,filename", "filename;timestamp",
                                    "t [ns]"])
def test_a_header_of_names_is_still_a_header(tmp_path, images, header):
    folder, paths = images
    f = tmp_path / "stamps.txt"
    body = ("1.0\n2.0\n3.0\n" if "," not in header and ";" not in header
            else "".join(f"{1.0 + k},{p.name}\n" for k, p in enumerate(paths)))
    f.write_text(f"{header}\n{body}")
    assert read_image_stamps(f, paths, folder) == [1_000_000_000, 2_000_000_000, 3_000_000_000]


def test_two_lines_whose_paths_end_in_one_image_are_refused(tmp_path, images):
    """``a/000000.png`` and ``b/000000.png`` both end in the image's name: before, the first
    line was taken silently."""
    folder, paths = images
    f = tmp_path / "stamps.txt"
    f.write_text("".join(f"{d}/{p.name} {k + 1}.5\n" for d in "ab" for k, p in enumerate(paths)))
    with pytest.raises(DatasetError, match="two lines name image 000000.png: a/000000.png and "
                                           "b/000000.png"):
        read_image_stamps(f, paths, folder)


def test_files_as_tools_write_them(tmp_path, images):
    """CRLF and a BOM (Windows tools), tabs, comments and trailing blank lines."""
    folder, paths = images
    f = tmp_path / "stamps.txt"
    f.write_bytes(b"\xef\xbb\xbf# stamps\r\n\t1.5\t# first\r\n2.5\r\n3.5\r\n\r\n \r\n")
    assert read_image_stamps(f, paths, folder) == [1_500_000_000, 2_500_000_000, 3_500_000_000]


def test_lines_naming_images_by_longer_paths_find_them(tmp_path):
    """Per-instant folders (``frames/*/left.png``) named in the file from anywhere above
    (``/data/run1/frames/0001/left.png``): each image's line by its path's end; the file's
    lines in any order."""
    folder = tmp_path / "frames"
    paths = [folder / f"{k:04d}" / "left.png" for k in range(40)]
    f = tmp_path / "stamps.txt"
    f.write_text("".join(f"/data/a b/run1/frames/{k:04d}/left.png,{100 + k}.25\n"
                         for k in reversed(range(40))))
    ns = read_image_stamps(f, paths, folder)
    assert ns == [(100 + k) * 1_000_000_000 + 250_000_000 for k in range(40)]
    f.write_text(f.read_text() + "/data/other/0003/left.png,7.5\n")
    with pytest.raises(DatasetError, match="two lines name image 0003/left.png"):
        read_image_stamps(f, paths, folder)


@pytest.mark.parametrize("line", ["{name},{stamp}", "{stamp}; {name}",
                                  "2011-09-26 13:02:{s:02d}.5,{name}"])
def test_names_with_spaces_in_a_comma_separated_file(tmp_path, line):
    """``My Frames/0001.png`` (a folder with a space, as Windows and macOS users name them) in
    a CSV: before, the line was split at the space too and refused."""
    folder = tmp_path / "My Frames é"
    paths = [folder / f"{k:04d} copy.png" for k in range(3)]
    f = tmp_path / "stamps.csv"
    f.write_text("".join(line.format(name=f"My Frames é/{p.name}", stamp=f"{10 + k}.5", s=k)
                         + "\n" for k, p in enumerate(paths)))
    ns = read_image_stamps(f, paths, folder)
    assert np.all(np.diff(ns) == 1_000_000_000) and len(ns) == 3


@pytest.mark.parametrize("in_file, on_disk", [("NFD", "NFC"), ("NFC", "NFD")])
def test_a_name_in_either_unicode_form_finds_its_image(tmp_path, in_file, on_disk):
    """``é`` composed (Linux, Windows) or decomposed (macOS's HFS+): one name. Before, a
    stamps file written in one form for images copied in the other was refused."""
    import unicodedata

    folder = tmp_path / unicodedata.normalize(on_disk, "Séquence")
    paths = [folder / unicodedata.normalize(on_disk, f"é{k}.png") for k in range(2)]
    f = tmp_path / "stamps.csv"
    f.write_text("".join(f"{unicodedata.normalize(in_file, p.name)},{k + 1}.5\n"
                         for k, p in enumerate(paths)))
    assert read_image_stamps(f, paths, folder) == [1_500_000_000, 2_500_000_000]
