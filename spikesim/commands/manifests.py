"""``spikesim manifests`` / ``spikesim manifests show NAME``: the built-in dataset manifests."""

from __future__ import annotations


def register(sub) -> None:
    p = sub.add_parser(
        "manifests", help="list the built-in dataset manifests, or print one to copy",
        description="Without arguments, list the built-in manifests (use them as builtin:NAME "
                    "with `spikesim dataset`). `show NAME` prints one as TOML, to copy and edit.")
    p.add_argument("action", nargs="?", choices=("show",), help="show: print one manifest")
    p.add_argument("name", nargs="?", help="manifest name (with or without builtin:)")
    p.set_defaults(func=run)


def run(args) -> int:
    from spikesim.dataset import BUILTIN_PREFIX, builtin_manifest_path, builtin_manifests
    from spikesim.errors import SpikeSimValueError

    if args.action is None:
        if args.name:
            raise SpikeSimValueError(f"unexpected {args.name!r}: use `spikesim manifests show "
                                     f"{args.name}`")
        for name, desc in builtin_manifests().items():
            print(f"{name:20s} {desc}")
        return 0
    if not args.name:
        raise SpikeSimValueError("NAME is required: `spikesim manifests show NAME` (names: "
                                 f"{', '.join(builtin_manifests())})")
    name = args.name[len(BUILTIN_PREFIX):] if args.name.startswith(BUILTIN_PREFIX) else args.name
    print(builtin_manifest_path(name).read_text(), end="")
    return 0
