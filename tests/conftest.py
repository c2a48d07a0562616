"""Puts tests/ on the import path, for the shared test helpers (taxi_grid.py,
experiment_file.py, oracle.py);
the suite imports its test files with --import-mode=importlib."""
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).parent))
