"""``spikesim demo``: the main job on built-in scenes (see spikesim.demo)."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser("demo", help="build a small dataset from built-in scenes, preview it, "
                                    "reconstruct it, and write report.md")
    p.add_argument("--out", default="demo_out", help="output folder (default: demo_out)")
    p.add_argument("--size", type=int, default=None, help="frame side in pixels (default 256)")
    p.add_argument("--limit", type=int, default=None, help="only the first N sequences")
    p.add_argument("--device", default=None,
                   help="torch device for SJDD-Net: cpu (default), cuda, cuda:N")
    p.add_argument("--threads", type=int, default=None,
                   help="torch threads per process (default 1 on the CPU: measured faster)")
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim.demo import run_demo

    r = run_demo(args.out, size=args.size, limit=args.limit, device=args.device,
                 threads=args.threads)
    print(f"{'sequence':26s} {'noise':5s} {'σ_g':>5s} {'σ_p':>5s} {'rate':>6s}")
    for s in r["sequences"]:
        print(f"{s['name']:26s} {s['noise']:5s} {s['sigma_g']:5.1f} {s['sigma_p']:5.1f} "
              f"{s['firing_rate']:6.3f}")
    rec = r["reconstruction"]
    if rec:
        print(f"\n{'method':24s} {'PSNR lin':>9s} {'SSIM lin':>9s} {'ms/frame':>9s}")
        for m in rec["methods"]:
            e = rec["summary"][m]["all"]
            print(f"{m:24s} {e['PSNR[linear]']:9.2f} {e['SSIM-gauss11[linear]']:9.4f} "
                  f"{e['ms_per_frame']:9.1f}")
    print(f"\nwrote {len(r['sequences'])} sequences and {args.out}/report.md")
    return 0
