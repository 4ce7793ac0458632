"""Evaluation reports: a text table, and a markdown page with matplotlib plots (PNG).

matplotlib is an optional extra ("report") and is imported only when plots are drawn. Plots:
heading over time with the (cos, sin) norm beneath and ambiguous frames marked (the paper's
figure 7, angle sequences only), error per body part per method (its figure 5), jitter per
method beside the ground truth's, and a real video's flexions and headings over time against
its reference (plot_real_video).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from regressor.angles import pose_angles
from regressor.errors import SilhouettePoseError

from lab.evaluation import METHODS, EvaluatedSequence


class ReportError(SilhouettePoseError, RuntimeError):
    """The report cannot be drawn (matplotlib missing) or written."""


#: Columns of the tables: (key, header, how to read it from a method's measures). The honest
#: measures stand beside the mean error: a flat output scores a small error, not a high skill.
_COMMON = [("error", "error", lambda m: m["error"]), ("jitter", "jitter", lambda m: m["jitter"]),
           ("accel_error", "accel_error", lambda m: m["accel_error"])]
_ANGLE_COLUMNS = _COMMON + [
    ("heading_rms_deg", "heading_rms", lambda m: m["heading_rms_deg"]),
    ("skill", "skill", lambda m: m.get("skill")),
    ("offset_free", "off53", lambda m: m.get("offset_free_error_deg")),
    ("corr8", "corr8", lambda m: m["top_angles"]["mean"] if "top_angles" in m else None),
    ("flexion", "flex_err", lambda m: m["flexion"]["error"] if "flexion" in m else None),
    ("flexion_corr", "flex_corr", lambda m: m["flexion"]["corr"] if "flexion" in m else None),
    ("mpjpe_mm", "mpjpe_mm", lambda m: m.get("mpjpe_mm")),
    ("pa_mpjpe_mm", "pa_mpjpe_mm", lambda m: m.get("pa_mpjpe_mm"))]
_POINT_COLUMNS = _COMMON + [
    ("skill", "skill", lambda m: m.get("skill")),
    ("corr8", "corr8", lambda m: m["top_coordinates"]["mean"] if "top_coordinates" in m
     else None)]


def _columns(result: dict) -> list:
    return _ANGLE_COLUMNS if result["units"] == "deg" else _POINT_COLUMNS


def _constant_row(result: dict) -> dict | None:
    """The constant baseline's figures, read off any method's measures (same for all)."""
    m = next(iter(result["methods"].values()))
    if "constant_error_deg" in m:       # angles: the error column is over all 54 angles
        return {"error": None, "body_error": m["constant_error_deg"], "skill": 0.0,
                "offset_free": m["constant_offset_free_error_deg"],
                "flexion": m["flexion"]["truth_mean_error_mean"],
                "mpjpe_mm": m["constant_mpjpe_mm"], "pa_mpjpe_mm": m["constant_pa_mpjpe_mm"]}
    if "constant_error" in m:
        return {"error": m["constant_error"], "skill": 0.0}
    return None


def _cell(value, width: int = 12) -> str:
    return f"{'-':>{width}s}" if value is None else f"{value:{width}.3f}"


def format_table(result: dict) -> str:
    """The methods' measures as a fixed-width text table (result: evaluation.evaluate()),
    with the constant baseline's row where there is one."""
    cols = _columns(result)
    lines = [f"{result['sequence']}: {result['frames']} frames, units {result['units']}",
             f"{'method':10s}" + "".join(f"{h:>12s}" for _, h, _ in cols)]
    for name, m in result["methods"].items():
        lines.append(f"{name:10s}" + "".join(_cell(get(m)) for _, _, get in cols))
    lines.append(f"{'truth':10s}{'':12s}{result['ground_truth_jitter']:12.3f}")
    const = _constant_row(result)
    if const is not None:
        lines.append(f"{'constant':10s}" + "".join(_cell(const.get(k)) for k, _, _ in cols))
    lines.extend(_angle_notes(result))
    if "runner_up" in result:
        r = result["runner_up"]
        lines.append(f"runner-up front/back hypothesis: shown on {r['runner_up_shown_ambiguous']}"
                     f" of {r['ambiguous_frames']} ambiguous frames, the true one (nearer the "
                     f"truth than the chosen) on {r['runner_up_true_ambiguous']}; on all frames "
                     f"shown {r['runner_up_shown']}, true {r['runner_up_true']}")
    return "\n".join(lines)


def _angle_notes(result: dict) -> list[str]:
    m = next(iter(result["methods"].values()))
    if "error_deg" not in m:
        return []
    body = ", ".join(f"{name} {v['error_deg']:.2f}" for name, v in result["methods"].items())
    return [f"53 body angles' error (the skill's): {body}; constant "
            f"{m['constant_error_deg']:.2f}. flex_err: knee/elbow flexion error; the constant "
            f"row's is the truth's own mean flexion (the training-mean pose's scores "
            f"{m['flexion']['constant_error_mean']:.2f}). off53: the 53 angles' error with each "
            f"angle's constant offset forgiven (the constant row's: the truth's own deviation, "
            f"what a still output scores)"]


def markdown_table(result: dict) -> str:
    """The same measures as a markdown table, with the constant baseline's row."""
    cols = _columns(result)
    rows = ["| method | " + " | ".join(h for _, h, _ in cols) + " |",
            "|---" * (len(cols) + 1) + "|"]

    def fmt(v):
        return "" if v is None else f"{v:.3f}"
    for name, m in result["methods"].items():
        rows.append(f"| {name} | " + " | ".join(fmt(get(m)) for _, _, get in cols) + " |")
    rows.append("| ground truth | | " + f"{result['ground_truth_jitter']:.3f} |"
                + " |" * (len(cols) - 2))
    const = _constant_row(result)
    if const is not None:
        rows.append("| constant (training mean) | "
                    + " | ".join(fmt(const.get(k)) for k, _, _ in cols) + " |")
    return "\n".join(rows + ["", *_angle_notes(result)])


def ambiguity_table(result: dict) -> str:
    """Markdown table of the heading-ambiguity analysis (angle sequences)."""
    rows = ["| estimate | ambiguous frames | frames with abs(heading error) > "
            f"{next(iter(result['ambiguity'].values()))['large_deg']:g} deg | of which ambiguous"
            " | heading RMS ambiguous / unambiguous (deg) |", "|---|---|---|---|---|"]
    for name, a in result["ambiguity"].items():
        share = a["share_of_large_in_ambiguous"]
        rms = [a["heading_rms_ambiguous_deg"], a["heading_rms_unambiguous_deg"]]
        rows.append(f"| {name} | {a['ambiguous_frames']}/{a['frames']} "
                    f"({100 * a['ambiguous_share']:.0f}%) | {a['large_error_frames']} | "
                    f"{a['large_errors_in_ambiguous']} "
                    f"({'-' if share is None else f'{100 * share:.0f}%'}) | "
                    + " / ".join("-" if r is None else f"{r:.1f}" for r in rms) + " |")
    return "\n".join(rows)


def _pyplot():
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:
        raise ReportError("plots need matplotlib: pip install 'silhouette-pose[report]'") from exc
    return plt


def check_plotting() -> None:
    """Raise ReportError now if plots cannot be drawn (matplotlib missing): before the work
    whose results they would show."""
    _pyplot()


def plot_heading(seq: EvaluatedSequence, path: Path, threshold: float) -> None:
    """Heading (deg) over frames, true vs stacked raw vs kalman, ambiguous frames shaded; the
    raw (cos, sin) norm beneath with the ambiguity threshold."""
    plt = _pyplot()
    t = np.arange(len(seq.truth))
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True,
                                      gridspec_kw={"height_ratios": [2, 1]})
    for ax in (top, bottom):
        for f in np.flatnonzero(seq.ambiguous):
            ax.axvspan(f - 0.5, f + 0.5, color="0.88", lw=0)
    top.plot(t, pose_angles(seq.truth)[:, 0], "k.", ms=3, label="true")
    top.plot(t, pose_angles(seq.estimates["stacked"])[:, 0], "C1.", ms=3, label="stacked (raw)")
    top.plot(t, pose_angles(seq.estimates["kalman"])[:, 0], "C0.", ms=3, label="kalman")
    top.set_ylabel("heading (deg)")
    top.set_ylim(-185, 185)
    top.legend(loc="upper right", fontsize=8, title="grey: ambiguous frames", title_fontsize=8)
    bottom.plot(t, seq.heading_norm, "C1-", lw=1)
    bottom.axhline(threshold, color="r", ls="--", lw=1, label=f"threshold {threshold:g}")
    bottom.set_ylabel("norm of (cos, sin)")
    bottom.set_xlabel("frame")
    bottom.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_parts(result: dict, path: Path) -> None:
    """Mean error per body part (angles) or per point, one bar group per part, bar per method."""
    plt = _pyplot()
    methods = list(result["methods"])
    parts = list(result["methods"][methods[0]]["per_part"])
    fig, ax = plt.subplots(figsize=(max(8, 0.45 * len(parts) * len(methods) / 2), 4))
    width = 0.8 / len(methods)
    x = np.arange(len(parts))
    for i, m in enumerate(methods):
        ax.bar(x + i * width, [result["methods"][m]["per_part"][p] for p in parts], width, label=m)
    ax.set_xticks(x + 0.4 - width / 2, parts, rotation=45 if len(parts) > 8 else 0, ha="right"
                  if len(parts) > 8 else "center", fontsize=8)
    ax.set_ylabel(f"mean error ({result['units']})")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_jitter(result: dict, path: Path) -> None:
    """Jitter per method with the ground truth's own jitter as a reference line."""
    plt = _pyplot()
    methods = list(result["methods"])
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.bar(methods, [result["methods"][m]["jitter"] for m in methods], color="C0")
    gt = result["ground_truth_jitter"]
    ax.axhline(gt, color="k", ls="--", lw=1, label=f"ground truth {gt:.3f}")
    ax.axhline(2 * gt, color="r", ls=":", lw=1, label="2x ground truth")
    ax.set_ylabel(f"jitter (mean |2nd difference|, {result['units']})")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_real_video(path: Path, views: list[dict], angle_names: list[str]) -> None:
    """One row per view of a real video with a 3-D reference: each flexion angle (degrees)
    over the video's frames, the reference's, the filtered and smoothed estimates' and a
    constant pose's, and the heading (degrees relative to the camera). views: dicts with
    "view" (name), "frames" (T,), "reference", "filtered", "smoothed" (T, A) flexions,
    "constant" (A,), "reference_heading", "filtered_heading", "smoothed_heading" (T,)."""
    plt = _pyplot()
    columns = len(angle_names) + 1
    fig, axes = plt.subplots(len(views), columns, figsize=(2.6 * columns, 2.1 * len(views)),
                             sharex=True, squeeze=False)
    for row, view in zip(axes, views):
        t = view["frames"]
        for a, (ax, name) in enumerate(zip(row, angle_names)):
            ax.plot(t, view["reference"][:, a], "k-", lw=1.5, label="reference")
            ax.plot(t, view["filtered"][:, a], "C0-", lw=1, label="filtered")
            ax.plot(t, view["smoothed"][:, a], "C2-", lw=1, label="smoothed")
            ax.axhline(view["constant"][a], color="0.5", ls="--", lw=1,
                       label="training-mean pose")
            top = max(150.0, np.nanmax([view[k][:, a].max() for k in
                                        ("reference", "filtered", "smoothed")]) + 5.0)
            ax.set_ylim(0, top)
            ax.set_title(f"{view['view']} {name}", fontsize=8)
        ax = row[-1]
        ax.plot(t, view["reference_heading"], "k.", ms=2, label="reference")
        ax.plot(t, view["filtered_heading"], "C0.", ms=2, label="filtered")
        ax.plot(t, view["smoothed_heading"], "C2.", ms=2, label="smoothed")
        ax.set_ylim(-185, 185)
        ax.set_title(f"{view['view']} heading", fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel("frame", fontsize=8)
    axes[0, 0].set_ylabel("flexion (deg)", fontsize=8)
    axes[0, 0].legend(fontsize=6, loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def write_report(folder: str | Path, seq: EvaluatedSequence, result: dict) -> Path:
    """Write README.md, the PNG plots and result.json into folder; returns the README's path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    angles = result["units"] == "deg"
    plot_parts(result, folder / "parts.png")
    plot_jitter(result, folder / "jitter.png")
    text = [f"# Evaluation: {result['sequence']}", "",
            f"{result['frames']} frames; errors in {result['units']}. Methods: "
            + ", ".join(m for m in METHODS if m in result["methods"]) + ".", "",
            markdown_table(result), ""]
    if angles:
        threshold = result["settings"]["filter"]["ambiguity_threshold"]
        plot_heading(seq, folder / "heading.png", threshold)
        text += ["## Heading and ambiguity", "",
                 "Heading over time (top) and the raw (cos, sin) norm (bottom); grey frames "
                 "are ambiguous (norm below the threshold).", "", "![heading](heading.png)", "",
                 ambiguity_table(result), ""]
    text += ["## Error per body part", "", "![parts](parts.png)", "",
             "## Jitter", "", "![jitter](jitter.png)", "",
             "## Settings", "", "```json", json.dumps(result["settings"], indent=1), "```", ""]
    (folder / "result.json").write_text(json.dumps(result, indent=1))
    readme = folder / "README.md"
    readme.write_text("\n".join(text))
    return readme
