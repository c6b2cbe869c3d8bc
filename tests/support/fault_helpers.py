"""Helpers of the fault suite: subprocess runs of the command lines, checks, small streams."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
FULL = os.environ.get("SPIKESIM_FAULTS", "").lower() == "full"
full_only = pytest.mark.skipif(not FULL, reason="full fault suite only (make test-faults)")


def cli_env(**extra) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.pop("SPIKESIM_DEBUG", None)
    env.update(extra)
    return env


def cli_command(prog: str, *args) -> list[str]:
    return [sys.executable, "-m", f"{prog}.cli", *map(str, args)]


def run_cli(prog: str, *args, cwd, timeout=240, preexec_fn=None, **kw):
    """Run ``spikesim``/``spikejdd`` in a subprocess; returns the CompletedProcess."""
    return subprocess.run(cli_command(prog, *args), cwd=cwd, env=cli_env(), capture_output=True,
                          text=True, timeout=timeout, preexec_fn=preexec_fn, **kw)


def assert_clean_failure(proc, *needles, code=1):
    """Non-zero exit, no traceback or crash, one ``error`` line naming ``needles``."""
    err = proc.stderr
    assert proc.returncode == code, (proc.returncode, err[-2000:])
    assert "Traceback" not in err and "Segmentation" not in err, err[-2000:]
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert lines, err[-2000:]
    for needle in needles:
        assert needle in lines[-1], (needle, lines[-1])


def no_temps(folder: Path) -> list[Path]:
    return [p for p in Path(folder).rglob(".*") if ".tmp-" in p.name]


def small_stream(n=96, height=16, width=20, cfa="RGGB", noise=True, clean_twin=False,
                 gt_readouts=(10, 50, 90)):
    import spikesim as ss

    sensor = ss.Sensor(height=height, width=width, cfa=cfa,
                       noise=ss.noise.PaperNoise(sigma_g=8.0) if noise else None)
    scene = ss.scenes.procedural("astronaut", motion="pan", size=(height, width))
    return ss.simulate(scene, sensor, n, seed=3, clean_twin=clean_twin,
                       gt_readouts=list(gt_readouts))




def write_manifest(path: Path, count=4, size=(64, 64), window=301, samples=2, noise=True,
                   name="faults") -> Path:
    """A TOML manifest of ``count`` procedural sequences of ``window * samples`` readouts."""
    noise_table = ('[[noise]]\nmode = "paper"\nlabel = "GN"\nsigma_g = 10.0\n' if noise else
                   '[[noise]]\nmode = "none"\nlabel = "clean"\n')
    path.write_text(
        f'[dataset]\nname = "{name}"\nseed = 7\nsize = [{size[0]}, {size[1]}]\n'
        f'window = {window}\nsamples_per_sequence = {samples}\n\n'
        '[sensor]\npreset = "ideal"\n\n' + noise_table +
        '\n[[sources]]\nkind = "procedural"\nscenes = ["astronaut", "coffee"]\n'
        f'motions = ["pan"]\nspeed = 500.0\ncount = {count}\nsplit = "train"\n'
    )
    return path


def set_file_limit(nbytes: int):
    """A ``preexec_fn`` giving the child an RLIMIT_FSIZE of ``nbytes``."""
    import resource

    def apply():
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))

    return apply


def finals(folder: Path) -> set[str]:
    return {p.name for p in Path(folder).rglob("*.h5") if not p.name.startswith(".")}


def children_of(pid: int) -> set[int]:
    """Process ids whose parent is ``pid`` (Linux /proc)."""
    out = set()
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.add(int(d.name))
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def run_cli_here(prog, argv):
    """``(exit code, stderr, stdout)`` of ``spikesim``/``spikejdd`` ``argv`` run in this process."""
    import contextlib
    import io

    if prog == "spikesim":
        from spikesim.cli import main
    else:
        from spikejdd.cli import main
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue(), out.getvalue()


def cli_fails(prog, argv, *needles):
    """Run ``argv``: it must exit 1 with a one-line error (no traceback) holding ``needles``;
    returns that line."""
    code, err, _ = run_cli_here(prog, argv)
    assert code == 1 and "Traceback" not in err, err
    line = [ln for ln in err.splitlines() if "error" in ln][-1]
    for n in needles:
        assert n in line, (n, line)
    return line
