"""Test-wide settings: helpers live in the ``tests.support`` package (the repository
root is on the import path through pytest's ``pythonpath`` setting in pyproject.toml)."""
