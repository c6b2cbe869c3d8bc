"""Where the shared fixtures live: ``<repo>/../shared/fixtures`` (as in CI), else /work/shared."""

from pathlib import Path

_CANDIDATES = (
    Path(__file__).resolve().parents[3] / "shared" / "fixtures",
    Path("/work/shared/fixtures"),
)
FIXTURES = next((p for p in _CANDIDATES if p.is_dir()), _CANDIDATES[0])
PEER_REDS = FIXTURES / "peer-reds"
