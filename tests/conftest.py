import sys
from pathlib import Path

# make tests/core/core_helpers.py and tests/core/fixture_paths.py importable as plain
# modules (only this folder: a folder named like a package would shadow it)
sys.path.insert(0, str(Path(__file__).parent / "core"))
