"""The README's speed and quality tables, generated from ``benchmarks/results``.

Every figure of the two tables comes from a JSON file that a benchmark wrote:

* speed: ``peers.json`` (``bench_peers.py``: spikesim beside Spike-Zoo's NumPy
  simulator), ``kernel.json`` (``bench_kernel.py``: throughput per noise mode
  and the NumPy float64 reference, same run) and ``kernel_ratios.json``
  (``bench_kernel.py --ratios-only``: physical over paper GN's throughput);
* quality: ``sjdd_sweep.json`` (``bench_sjdd.py``: SJDD-Net and the classical
  pipelines on one sweep, PSNR/SSIM in linear light and time per frame).

The README holds each table between two marker comments,
``<!-- tables:NAME:start -->`` and ``<!-- tables:NAME:end -->`` (NAME is
``speed`` or ``quality``). Run::

    python benchmarks/readme_tables.py            # print both tables
    python benchmarks/readme_tables.py --check    # exit 1 if README.md's tables differ
    python benchmarks/readme_tables.py --write    # put the generated tables into README.md

after a benchmark has rewritten its JSON file.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
README = ROOT / "README.md"
NAMES = ("speed", "quality")

_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")

#: Readers' names of the noise labels bench_kernel.py writes (its own labels stay in the JSON).
_NOISE = {
    "off": "off",
    "paper GN σ=10": "paper GN, σ_g = 10",
    "paper GPN σg=σp=2.5": "paper GPN, σ_g = σ_p = 2.5",
    "physical (defaults)": "physical (all sources, shot noise per spike)",
}

#: What each method of the SJDD sweep is (names as ``spikejdd methods`` lists them).
_METHOD = {
    "sjdd": "SJDD-Net, `sjdd-full` weights, window and its transpose averaged",
    "sjdd-1view": "SJDD-Net, `sjdd-full` weights, one view",
    "sjdd@sjdd-lite": "SJDD-Net, CPU-trained `sjdd-lite` weights",
}


class TablesError(Exception):
    """A results file or a README marker is missing or malformed."""


def sci(x: float) -> str:
    """``x`` with three significant digits as ``m.mm·10ᵉ``."""
    mantissa, exponent = f"{x:.2e}".split("e")
    return f"{mantissa}·10{str(int(exponent)).translate(_SUPERSCRIPT)}"


def _load(results: Path, name: str, command: str) -> dict:
    path = results / name
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise TablesError(f"{path} is missing: run `{command}` first") from None
    except json.JSONDecodeError as err:
        raise TablesError(f"{path} is not valid JSON ({err}): run `{command}` again") from None


def _get(data: dict, path: str, keys: tuple[str, ...]):
    value = data
    for key in keys:
        if not isinstance(value, dict) or key not in value:
            raise TablesError(f"{path} has no entry {' → '.join(keys)!r}: rerun its benchmark")
        value = value[key]
    return value


def _ms(ms: float) -> str:
    return f"{ms:.1f}" if ms < 100 else f"{ms:.0f}"


def _span(stats: dict) -> str:
    return f"{stats['median']:.2f}× [{stats['min']:.2f}–{stats['max']:.2f}]"


def speed_table(results: Path = RESULTS) -> str:
    """Markdown: spikesim beside Spike-Zoo, and spikesim's throughput per noise mode."""
    peers = _load(results, "peers.json", "python benchmarks/bench_peers.py")
    kernel = _load(results, "kernel.json", "python benchmarks/bench_kernel.py")
    ratios = _load(results, "kernel_ratios.json",
                   "python benchmarks/bench_kernel.py --ratios-only --size 1000")

    scene = _get(peers, "peers.json", ("scene",))
    m = re.match(r"(\d+)x(\d+) (\w+) (\w+), (\d+) readouts", scene)
    if m is None:
        raise TablesError(f"peers.json's scene {scene!r} does not name its size and readouts")
    px_readouts = int(m[1]) * int(m[2]) * int(m[5])
    median_s = _get(peers, "peers.json", ("median_s",))
    low, high = _get(peers, "peers.json", ("speedup_range",))
    pairs = _get(peers, "peers.json", ("pairs",))
    peer_scene = f"{m[1]}×{m[2]} {m[3]}, {m[4]}, {m[5]} readouts"

    rows = {(r["scene"], r["noise"]): r for r in _get(kernel, "kernel.json", ("rows",))}
    size = "×".join(str(n) for n in _get(kernel, "kernel.json", ("size",)))
    cfa = _get(kernel, "kernel.json", ("cfa",))

    lines = [
        "| simulator | scene | noise | pixel-readouts/s, static | pixel-readouts/s, moving "
        "| speed-up |",
        "|---|---|---|---:|---:|---|",
        f"| **spikesim** | {peer_scene} | off | {sci(px_readouts / median_s['spikesim'])} | — "
        f"| **{peers['speedup_median']:.0f}×** Spike-Zoo's ({low:.0f}–{high:.0f}× "
        f"over {pairs} alternating pairs) |",
        f"| Spike-Zoo `video2spike_simulation` (NumPy) | {peer_scene} | off "
        f"| {sci(px_readouts / median_s['spikezoo'])} | — | 1× |",
    ]
    for noise, label in _NOISE.items():
        static, moving = rows.get(("static", noise)), rows.get(("moving", noise))
        if static is None or moving is None:
            raise TablesError(f"kernel.json has no static and moving rows for noise {noise!r}: "
                              "rerun python benchmarks/bench_kernel.py")
        if static.get("speedup") is not None:
            versus = (f"{static['speedup']:.0f}× / {moving['speedup']:.0f}× the NumPy "
                      "float64 reference")
        else:
            key = "{}: physical throughput / paper GN's"
            versus = "{:.2f}× / {:.2f}× paper GN's, same run".format(
                *(_get(kernel, "kernel.json", ("same_run_ratios", key.format(s),
                                               "per-spike shot noise"))["median"]
                  for s in ("static", "moving")))
        lines.append(f"| spikesim | {size} {cfa} | {label} "
                     f"| {sci(static['kernel_px_readouts_per_s'])} "
                     f"| {sci(moving['kernel_px_readouts_per_s'])} | {versus} |")
    if not all(r.get("bit_identical") in (True, None) for r in rows.values()):
        raise TablesError("kernel.json has a row whose output differs from the NumPy "
                          "reference: fix the kernel before quoting it")

    later = _get(ratios, "kernel_ratios.json", ("same_run_ratios",))
    key = "{}: physical throughput / paper GN's"
    dim = [k for k in later if k.startswith("static ×") and k.endswith("paper GN's")]
    if not dim:
        raise TablesError("kernel_ratios.json has no dimmed static scene: rerun "
                          "python benchmarks/bench_kernel.py --ratios-only --size 1000")
    rate_key = dim[0].replace("throughput / paper GN's", "spikes per readout")
    dim_rate = _get(ratios, "kernel_ratios.json", ("same_run_ratios", rate_key, ""))
    lines += [
        "",
        f"Physical mode over paper GN's throughput in a later run "
        f"(`{ratios['command']}`, {ratios['readouts_per_call']}-readout calls, median "
        f"[range] of 3 rounds): "
        f"{_span(later[key.format('static')]['per-spike shot noise'])} static, "
        f"{_span(later[key.format('moving')]['per-spike shot noise'])} moving, "
        f"{_span(later[dim[0]]['per-spike shot noise'])} on the static scene dimmed to "
        f"{dim_rate['median']:.3f} spikes per readout.",
        "",
        f"Machines: first two rows, `python benchmarks/bench_peers.py`: {peers['machine']}. "
        f"Other rows, `{kernel['command']}` (one run, output bit-identical to the NumPy "
        f"reference): {kernel['machine']}, Python {kernel['python']}; the ratio run: "
        f"{ratios['machine']}.",
    ]
    return "\n".join(lines)


def quality_table(results: Path = RESULTS) -> str:
    """Markdown: SJDD-Net beside the classical pipelines on one sweep (PSNR, SSIM, time)."""
    sweep = _load(results, "sjdd_sweep.json", "python benchmarks/bench_sjdd.py")
    summary = _get(sweep, "sjdd_sweep.json", ("summary",))
    config = _get(sweep, "sjdd_sweep.json", ("config",))
    lines = [
        "| method | PSNR (dB), linear | SSIM, linear | PSNR (dB), sRGB | SSIM, sRGB "
        "| ms per frame |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    classical = {}
    for method in _get(sweep, "sjdd_sweep.json", ("methods",)):
        s = _get(sweep, "sjdd_sweep.json", ("summary", method, "all"))
        name = f"`{method}`" + (f" ({_METHOD[method]})" if method in _METHOD else "")
        if method == "sjdd":
            name = f"**{name}**"
        elif not method.startswith("sjdd"):
            classical[method] = s["PSNR[linear]"]
        lines.append(f"| {name} | {s['PSNR[linear]']:.2f} | {s['SSIM-gauss11[linear]']:.3f} "
                     f"| {s['PSNR[srgb]']:.2f} | {s['SSIM-gauss11[srgb]']:.3f} "
                     f"| {_ms(s['ms_per_frame'])} |")
    if "sjdd" not in summary or not classical:
        raise TablesError("sjdd_sweep.json lacks `sjdd` or a classical pipeline: rerun "
                          "python benchmarks/bench_sjdd.py")
    best = max(classical, key=classical.get)
    gain = summary["sjdd"]["all"]["PSNR[linear]"] - classical[best]
    h, w = config["size"]
    frames = summary["sjdd"]["all"]["frames"]
    lines += [
        "",
        f"SJDD-Net over the best classical pipeline (`{best}`): {gain:+.2f} dB. "
        f"{frames} frames of {h}×{w} per method: {len(config['sets'])} motion sets "
        f"({', '.join(config['sets'])}), noise {', '.join(config['levels'])}; "
        f"{config['context']}-readout windows. Time per frame on CPU, median of "
        f"{config['repeats']} calls after a warm-up. "
        f"`{sweep['command']}` on {sweep['machine']['description']}.",
    ]
    return "\n".join(lines)


def generate(results: Path = RESULTS) -> dict[str, str]:
    """Each table's Markdown by name."""
    return {"speed": speed_table(results), "quality": quality_table(results)}


def _markers(name: str) -> tuple[str, str]:
    return f"<!-- tables:{name}:start -->", f"<!-- tables:{name}:end -->"


def sections(text: str) -> dict[str, str]:
    """The text between each pair of marker comments of ``text`` (without the markers'
    own blank lines around it)."""
    found = {}
    for name in NAMES:
        start, end = _markers(name)
        if text.count(start) != 1 or text.count(end) != 1:
            raise TablesError(f"README.md needs exactly one {start} and one {end} "
                              f"around the {name} table")
        body = text.split(start, 1)[1].split(end, 1)[0]
        found[name] = body.strip("\n")
    return found


def replace(text: str, tables: dict[str, str]) -> str:
    """``text`` with each marked section replaced by its generated table."""
    sections(text)   # checks the markers
    for name, table in tables.items():
        start, end = _markers(name)
        before, rest = text.split(start, 1)
        after = rest.split(end, 1)[1]
        text = f"{before}{start}\n{table}\n{end}{after}"
    return text


def differences(text: str, tables: dict[str, str]) -> list[str]:
    """One line per table of ``text`` that differs from its generated form."""
    found = sections(text)
    out = []
    for name, table in tables.items():
        have, want = found[name].splitlines(), table.splitlines()
        if have == want:
            continue
        for i, (a, b) in enumerate(zip(have, want, strict=False)):
            if a != b:
                where = f"line {i + 1} of the table: {a[:60]!r} should be {b[:60]!r}"
                break
        else:
            where = f"{len(have)} lines where {len(want)} are generated"
        out.append(f"README.md's {name} table differs from benchmarks/results ({where}); "
                   "run python benchmarks/readme_tables.py --write")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--check", action="store_true",
                      help="exit 1 if the README's tables differ from the generated ones")
    mode.add_argument("--write", action="store_true",
                      help="replace the README's marked tables with the generated ones")
    parser.add_argument("--readme", type=Path, default=README, help="the README (README.md)")
    parser.add_argument("--results", type=Path, default=RESULTS,
                        help="the folder of results JSON files (benchmarks/results)")
    args = parser.parse_args(argv)
    try:
        tables = generate(args.results)
        if not (args.check or args.write):
            print("\n\n".join(tables[name] for name in NAMES))
            return 0
        try:
            text = args.readme.read_text(encoding="utf-8")
        except FileNotFoundError:
            raise TablesError(f"{args.readme} does not exist: pass --readme PATH") from None
        if args.check:
            problems = differences(text, tables)
            for line in problems:
                print(line, file=sys.stderr)
            return 1 if problems else 0
        new = replace(text, tables)
        if new != text:
            args.readme.write_text(new, encoding="utf-8")
        return 0
    except TablesError as err:
        print(f"readme_tables: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
