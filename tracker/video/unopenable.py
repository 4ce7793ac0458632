"""Why OpenCV refused a video file, or a file decodes nothing, in one line (imported only then)."""
from __future__ import annotations

from pathlib import Path

from tracker.video.decode import VideoError, VideoSource


def nothing_decodes(source: VideoSource) -> VideoError:
    """The error for a file that opened but decodes nothing in the range asked for."""
    start_s = source.start_index / source.fps
    return VideoError(f"{source.path}: no decodable frames from {start_s:g} s on (a cut-off "
                      f"or damaged file?)")


def _mp4_top_level_boxes(path: Path) -> dict[bytes, int] | None:
    """Top-level ISO-BMFF boxes of ``path`` as {type: payload size}, or None if not an MP4/MOV;
    reads only the box headers. Used only to explain why OpenCV refused a file."""
    boxes: dict[bytes, int] = {}
    size_total = path.stat().st_size
    with path.open("rb") as f:
        offset = 0
        while offset + 8 <= size_total:
            f.seek(offset)
            header = f.read(16)
            size = int.from_bytes(header[:4], "big")
            kind = header[4:8]
            header_len = 8
            if size == 1 and len(header) == 16:
                size, header_len = int.from_bytes(header[8:16], "big"), 16
            elif size == 0:  # box runs to the end of the file
                size = size_total - offset
            if offset == 0 and kind != b"ftyp":
                return None
            if size < header_len:
                break
            boxes[kind] = boxes.get(kind, 0) + min(size, size_total - offset) - header_len
            offset += size
    return boxes


def why_unopenable(path: Path) -> str:
    """One-line reason OpenCV could not open an existing file."""
    if path.stat().st_size == 0:
        return "is empty (0 bytes)"
    boxes = _mp4_top_level_boxes(path)
    if boxes is None:
        return "is not a video OpenCV can decode (unknown format or not a video file)"
    if b"moov" not in boxes:
        return "is a truncated MP4: its index ('moov' box) is missing (file cut off?)"
    if boxes.get(b"mdat", 0) == 0:
        return "contains no video frames"
    return "is an MP4 OpenCV cannot decode (no supported video stream)"
