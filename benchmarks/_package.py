"""The repository root on ``sys.path`` and its one loader (``package_loader``), for the benchmarks."""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from package_loader import load_package  # noqa: E402,F401
