"""``spikesim demo``: the main job on built-in scenes (see spikesim.demo)."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("demo", help="simulate built-in scenes, write HDF5, previews and a report")
    p.add_argument("--out", default="demo_out", help="output folder (default: demo_out)")
    p.add_argument("--size", type=int, default=256, help="frame side in pixels (default 256)")
    p.add_argument("--readouts", type=int, default=801, help="readouts per sequence")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim.demo import run_demo

    results = run_demo(args.out, size=args.size, n_readouts=args.readouts, seed=args.seed)
    print(f"{'sequence':34s} {'preset':9s} {'rate':>6s} {'px·readouts/s':>14s} {'TFP PSNR':>9s}")
    for r in results:
        print(f"{r.name:34s} {r.preset:9s} {r.firing_rate:6.3f} {r.px_readouts_per_s:14.3g} "
              f"{r.tfp_psnr_db:8.2f}")
    print(f"wrote {len(results)} sequences, previews and {args.out}/report.md")
    return 0
