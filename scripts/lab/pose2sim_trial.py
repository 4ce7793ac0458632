"""The Pose2Sim trial checked before long work (evaluate_real.py, evaluate_silhouettes.py,
draw_fitted_body.py): sequences.pose2sim.load_trial with one-line errors for what it would
otherwise find late or as a traceback."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sequences.pose2sim import (DEFAULT_TRIAL, VIEWS, Pose2SimError, Trial, calibration_path,
                                load_trial, reference_path)
from tracker.video.decode import open_video


def missing_trial(root: Path) -> str | None:
    """The usage error for a --trial folder that does not exist (the default one pointed at
    as such), or None."""
    if root.is_dir():
        return None
    default = (" (the default, in the shared data beside the repository; give --trial)"
               if root == DEFAULT_TRIAL else "")
    return f"--trial {root}: no such folder{default}"


def trial_files(root: Path) -> list[tuple[str, Path]]:
    """(description, path) of every file a script reads from the trial at ``root``: the
    reference, the calibration and each view's video (the inputs of check_outputs)."""
    return [("the reference", reference_path(root)), ("the calibration", calibration_path(root)),
            *((f"the {view} video", root / "videos" / f"{view}.mp4") for view in VIEWS)]


def checked_trial(root: Path, views=VIEWS) -> Trial:
    """load_trial(root), with one-line errors (Pose2SimError naming the file) also for a
    reference or calibration that is not text, for a calibration whose numbers are not all
    finite (a NaN there only showed later, as warnings and a misleading error), and for a
    video of views missing or undecodable (found after minutes of fitting and tracking, else;
    VideoError)."""
    try:
        trial = load_trial(root)
    except UnicodeDecodeError as exc:
        files = [reference_path(root), calibration_path(root)]
        binary = [str(path) for path in files if not _is_text(path)] or map(str, files)
        raise Pose2SimError(f"{' or '.join(binary)}: not a text file ({exc.reason} at byte "
                            f"{exc.start})") from None
    for view, camera in trial.cameras.items():
        if not all(np.isfinite(a).all() for a in (camera.K, camera.distortion, camera.R,
                                                  camera.t)):
            raise Pose2SimError(f"{calibration_path(root)}: camera {view} has a number that is not "
                                f"finite (NaN or infinity)")
    for view in views:
        open_video(trial.video(view))       # decodes its first frame: a fraction of a second
    return trial


def _is_text(path: Path) -> bool:
    """Whether the file reads as UTF-8 text (what load_trial expects)."""
    try:
        path.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        return False
    except OSError:
        pass                            # not this one's problem
    return True
