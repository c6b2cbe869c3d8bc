import sys
from pathlib import Path

# make dataset_helpers.py importable as a plain module (tests run with --import-mode=importlib)
sys.path.insert(0, str(Path(__file__).parent))
