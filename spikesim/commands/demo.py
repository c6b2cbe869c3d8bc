"""``spikesim demo``: the simulation half of the main job (see spikesim.demo); ``spikejdd
demo`` adds the reconstruction."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("demo", help="build a small dataset from built-in scenes, preview it and "
                                    "write report.md (`spikejdd demo` also reconstructs it)")
    p.add_argument("--out", default="demo_out", help="output folder (default: demo_out)")
    p.add_argument("--size", type=int, default=None, help="frame side in pixels (default 256)")
    p.add_argument("--limit", type=int, default=None, help="only the first N sequences")
    p.set_defaults(func=run)


def print_sequences(r: dict) -> None:
    print(f"{'sequence':26s} {'noise':5s} {'σ_g':>5s} {'σ_p':>5s} {'rate':>6s}")
    for s in r["sequences"]:
        print(f"{s['name']:26s} {s['noise']:5s} {s['sigma_g']:5.1f} {s['sigma_p']:5.1f} "
              f"{s['firing_rate']:6.3f}")


def run(args) -> int:
    import json
    from pathlib import Path

    from spikesim.demo import Stages, build_demo, demo_report, preview_report

    stages = Stages("spikesim demo", 3)  # each stage said on stderr as it starts and ends
    r = build_demo(args.out, size=args.size, limit=args.limit, stages=stages)
    out = Path(args.out)
    with stages("writing report.md and summary.json"):
        (out / "summary.json").write_text(json.dumps(r, indent=1, default=str))
        (out / "report.md").write_text("\n".join(demo_report(r) + preview_report(r)))
    print_sequences(r)
    print(f"\nwrote {len(r['sequences'])} sequences and {args.out}/report.md; "
          "`spikejdd demo` also reconstructs them")
    return 0
