"""``spikesim convert SRC DST``: between spikesim HDF5 and PKU ``.dat`` (either way).

The direction follows the names: ``DST`` ending in ``.dat`` writes PKU
frames, anything else (``.h5``) a spikesim HDF5 file.  Streams in blocks, so
captures larger than memory convert; the output appears only when complete.
"""

from __future__ import annotations

from pathlib import Path

from spikesim.commands._io_common import add_source_options, parse_crop, source_from_args

__all__ = ["register", "run", "convert"]

BLOCK_READOUTS = 256


def register(subparsers) -> None:
    from spikesim.io import DEFAULT_COMPRESSION

    p = subparsers.add_parser(
        "convert", help="convert between spikesim HDF5 and PKU .dat",
        description="Convert a spike stream between spikesim HDF5 (.h5) and PKU .dat; the "
                    "output format follows DST's suffix.",
    )
    p.add_argument("src", help="a .h5 file, a dataset folder (see --sequence) or a .dat")
    p.add_argument("dst", help="output file: *.dat or *.h5")
    p.add_argument("--start", type=int, default=0, help="first readout to convert (default 0)")
    p.add_argument("--length", type=int, default=None, help="readouts to convert (default all)")
    p.add_argument("--crop", type=parse_crop, default=None, metavar="TOP,LEFT,HEIGHT,WIDTH",
                   help="spatial crop in pixels")
    p.add_argument("--out-no-flip", dest="out_flip", action="store_false",
                   help=".dat output: store top row first (default: upside down, as PKU tools)")
    p.add_argument("--compression", default=DEFAULT_COMPRESSION,
                   help=f"HDF5 output: none, gzip[:1-9], lz4, zstd[:1-22] "
                        f"(default {DEFAULT_COMPRESSION})")
    p.add_argument("--sjdd", action="store_true",
                   help="export SRC (file or dataset folder) to the SJDD-Net training layout "
                        "under the folder DST (spk/<noise>/<subset>/*.dat, gt/<subset>/*.npy)")
    p.add_argument("--subset", default="spikesim", help="--sjdd: subset folder name")
    p.add_argument("--noise", default="auto",
                   help="--sjdd: noise folder name (default: from the noise configuration)")
    p.add_argument("--gt-encoding", choices=("linear", "srgb"), default="linear",
                   help="--sjdd: ground truth in linear light (default) or sRGB-encoded")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    add_source_options(p)
    p.set_defaults(func=run)


def convert(src, dst, start: int = 0, length: int | None = None, crop=None,
            out_flip: bool = True, compression: str | None = None,
            progress: bool = False) -> Path:
    """Copy readouts ``start .. start+length-1`` (and a crop) of ``src`` into ``dst``.

    ``src`` is a Sequence or DatFile; ``dst`` a path whose suffix picks the
    format.  Ground-truth frames inside the window go along to HDF5 output
    (with their readout indices shifted to the window).
    """
    from tqdm.auto import tqdm

    from spikesim._validate import check_crop, check_window
    from spikesim.cfa import cfa_after_crop
    from spikesim.io import DEFAULT_COMPRESSION, compression_kwargs
    from spikesim.io.dat import DatWriter
    from spikesim.io.h5 import H5Writer
    from spikesim.io.source import is_dat

    start, length = check_window(start, length, src.n_readouts)
    top, left, h, w = check_crop(crop, src.height, src.width)
    if not is_dat(dst):
        compression_kwargs(compression or DEFAULT_COMPRESSION)  # refused before any work
    box = (top, left, h, w)
    bar = tqdm(total=length, disable=not progress, unit="readout", desc=Path(dst).name)
    if is_dat(dst):
        writer = DatWriter(dst, h, w, flip=out_flip)
        add_gt = None
    else:
        meta = dict(src.meta)
        meta.update(height=h, width=w, cfa=cfa_after_crop(src.cfa, top, left),
                    clock_hz=src.clock_hz or None, n_readouts=length,
                    start_readout=int(meta.get("start_readout") or 0) + start,
                    converted_from={"path": str(src.path), "start": start, "crop": list(box)})
        writer = H5Writer(dst, meta, compression=compression or DEFAULT_COMPRESSION,
                          clean=bool(src.has_clean))
        add_gt = writer.add_gt
    with bar, writer:
        for t in range(start, start + length, BLOCK_READOUTS):
            n = min(BLOCK_READOUTS, start + length - t)
            packed = src.read_window(t, n, box, packed=True)
            if isinstance(writer, DatWriter):
                writer.write_packed(packed)
            else:
                clean = src.read_window(t, n, box, packed=True, clean=True) \
                    if src.has_clean else None
                writer.append(packed, clean)
            bar.update(n)
        if add_gt is not None:
            for k, idx in enumerate(src.gt_index):
                if start <= idx < start + length:
                    add_gt(src.read_gt(k, box)[None], [int(idx) - start])
    return Path(dst)


def run(args) -> int:
    if args.sjdd:
        from spikesim.commands._io_common import resolve_path
        from spikesim.io.export import export_sjdd

        summary = export_sjdd(resolve_path(args.src, args.split), args.dst,
                              subset=args.subset, noise=args.noise,
                              gt_encoding=args.gt_encoding, progress=not args.quiet,
                              option_names={"noise": "--noise", "subset": "--subset",
                                            "gt_encoding": "--gt-encoding"})
        for e in summary["exports"]:
            print(f"wrote {e['samples']} samples: {e['spk_dir']} and {e['gt_dir']} "
                  f"(SJDD-Net noise {e['noise_folder']}, eval_set {e['subset']})")
        print(f"color_mode {summary['color_mode']}; skipped {len(summary['skipped'])} GT "
              "readouts without a full 39-readout window")
        return 0
    from spikesim.errors import bad_value

    if not args.dst.lower().endswith((".dat", ".h5", ".hdf5")):
        raise bad_value("DST", args.dst, "a path ending in .dat, .h5 or .hdf5")
    if Path(args.dst).exists() and Path(args.src).exists() and \
            Path(args.dst).resolve() == Path(args.src).resolve():
        raise bad_value("DST", args.dst, "another file than SRC: the source would be replaced "
                        "by its converted copy")
    from spikesim.cli_guard import as_option
    from spikesim.errors import SpikeSimValueError
    from spikesim.io import compression_kwargs

    try:
        compression_kwargs(args.compression)
    except SpikeSimValueError as exc:
        raise as_option(exc, {"compression": "--compression"}) from None
    src = source_from_args(args, args.src)
    from spikesim._validate import check_crop, check_window

    try:  # the window and crop checked here, to name the options
        check_window(args.start, args.length, src.n_readouts)
        check_crop(args.crop, src.height, src.width)
    except SpikeSimValueError as exc:
        named = as_option(exc, {"start": "--start", "length": "--length", "crop": "--crop"})
        raise type(named)(str(named).replace(", start=", ", --start ")) from None
    out = convert(src, args.dst, args.start, args.length, args.crop, out_flip=args.out_flip,
                  compression=args.compression, progress=not args.quiet)
    print(f"wrote {out}")
    return 0
