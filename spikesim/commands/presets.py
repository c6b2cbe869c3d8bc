"""``spikesim presets``: list the sensor presets."""

from __future__ import annotations

import json


def register(sub) -> None:
    p = sub.add_parser("presets", help="list sensor presets")
    p.add_argument("--json", action="store_true", help="print full configurations as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim.sensor import Sensor, list_presets

    presets = list_presets()
    if args.json:
        print(json.dumps({k: Sensor.preset(k).to_dict() for k in presets}, indent=2))
        return 0
    width = max(map(len, presets))
    for name, desc in presets.items():
        print(f"{name:{width}s}  {desc}")
    return 0
