import sys
from pathlib import Path

# make tests/<area>/helpers.py importable as plain modules
sys.path.insert(0, str(Path(__file__).parent / "core"))
