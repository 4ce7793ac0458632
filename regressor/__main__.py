"""``python -m regressor describe [MODEL]``: print what a model file holds, as JSON.

MODEL defaults to the shipped model. A missing, foreign or tampered file is refused in one
line (exit 1); a usage mistake exits 2, as argparse does.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(prog="python -m regressor", description="Tools for silhouette-pose models.")
    commands = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    describe = commands.add_parser("describe", help="print a model file's regressor, parts, "
                                   "training data and settings as JSON")
    describe.add_argument("model", nargs="?", type=Path, default=None,
                          help="model file (default: the shipped model)")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from .describe import describe_model
    from .errors import SilhouettePoseError
    from .pose_model import DEFAULT_MODEL_PATH, load_pose_model
    try:
        model = load_pose_model(args.model or DEFAULT_MODEL_PATH)
    except SilhouettePoseError as exc:
        print(f"python -m regressor: error: {exc}", file=sys.stderr)
        return 1
    info = {"model": str(args.model or DEFAULT_MODEL_PATH), **describe_model(model)}
    try:
        print(json.dumps(info, indent=2))
    except BrokenPipeError:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
