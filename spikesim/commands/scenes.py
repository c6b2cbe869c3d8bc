"""``spikesim scenes``: list the procedural scenes, camera motions and flow methods."""

from __future__ import annotations

import argparse
import json

__all__ = ["register", "run"]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "scenes",
        help="list procedural scenes, motions and optical-flow methods",
        description="List the built-in procedural scenes (spikesim.scenes.procedural), the "
        "camera motions for picture scenes, and the optical-flow methods for video.",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object instead")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from spikesim.motion import DEFAULT_FLOW, FLOW_METHODS
    from spikesim.scenes import list_motions, list_scenes

    scenes, motions = list_scenes(), list_motions()
    if args.json:
        print(json.dumps({"scenes": scenes, "motions": motions, "flow_methods": FLOW_METHODS,
                          "default_flow": DEFAULT_FLOW}, indent=2))
        return 0
    for title, table in (("scenes", scenes), ("motions (picture scenes)", motions),
                         (f"flow methods (default {DEFAULT_FLOW})", FLOW_METHODS)):
        print(f"{title}:")
        width = max(len(k) for k in table)
        for name, desc in table.items():
            print(f"  {name:<{width}}  {desc}")
    return 0
