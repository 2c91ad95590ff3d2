import os
import sys
from pathlib import Path

os.environ.setdefault("MPLBACKEND", "Agg")

# benchmarks/_reference_search.py: the exhaustive searches the tests compare the index with
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
