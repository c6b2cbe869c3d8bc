import sys
from pathlib import Path

# make tests/fixture_paths.py and tests/core/core_helpers.py importable as plain modules
sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parent / "core"))
