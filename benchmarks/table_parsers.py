"""Compiled CSV readers and writers against the ones hexcal's table paths use (issue 20, item 4).

``python benchmarks/table_parsers.py [--rows N]`` writes a pose file of N rows (ids and
``x..c``, default 1,000,000) with hexcal's writer and times, each in a fresh subprocess of
this interpreter (its import included, as a command pays it), the CPU seconds of:

- reading the six number columns: ``np.loadtxt`` (numpy's C reader, what hexcal's fast path
  calls), ``pyarrow.csv.read_csv`` and ``polars.read_csv`` (both compiled, well kept);
- writing the same numbers: hexcal's ``format(v, ".15g")`` formatter
  (:func:`hexcal.io.table_writing.format_rows`, the bytes of hexcal's files), and
  ``pyarrow.csv.write_csv`` (shortest round-trip digits: other bytes than hexcal's files).

Each is run with one thread and with the machine's threads (``use_threads`` /
``POLARS_MAX_THREADS``), and printed as a ratio to numpy's reader (or hexcal's writer) in the
same run. A library that is not installed is skipped with a line; install it in a scratch
environment (``pip install pyarrow polars``) to time it: hexcal depends on neither.

The question it answers: can a well-kept compiled reader or writer make the table paths of
``ik``/``fk``/``compensate`` 4x faster in CPU time (:mod:`benchmarks.tables`)? Only if it
costs much less CPU than numpy's reader and hexcal's formatter, which take most of what is
left of the file path.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

MAKE = r"""
import sys
import numpy as np
from hexcal.io import write_poses

n = int(sys.argv[2])
low = np.array([-250, -250, 700, -0.17, -0.17, -0.17])
poses = np.random.default_rng(0).uniform(low, -low * [1, 1, -9 / 7, 1, 1, 1], (n, 6))
write_poses(sys.argv[1], poses, ids=[f"p{k}" for k in range(n)])
"""

#: Each case: code run after ``path``, ``threads`` and ``start = time.process_time()`` are set;
#: it leaves the values read in ``values`` (``(n, 6)``) or writes ``out``.
CASES = {
    "numpy.loadtxt (read)": r"""
import numpy as np
values = np.loadtxt(path, delimiter=",", usecols=range(1, 7), skiprows=1, comments=None,
                    quotechar=None, ndmin=2)
""",
    "pyarrow.csv.read_csv (read)": r"""
import numpy as np
import pyarrow as pa
import pyarrow.csv as pc
names = list("xyzabc")
table = pc.read_csv(path, read_options=pc.ReadOptions(use_threads=threads > 1),
                    parse_options=pc.ParseOptions(quote_char=False),
                    convert_options=pc.ConvertOptions(column_types={c: pa.float64() for c in names},
                                                      include_columns=names))
values = np.column_stack([table.column(c).to_numpy() for c in names])
""",
    "polars.read_csv (read)": r"""
import polars as pl
names = list("xyzabc")
values = pl.read_csv(path, columns=names, schema_overrides={c: pl.Float64 for c in names},
                     quote_char=None).to_numpy()
""",
    "hexcal format_rows + write (write)": r"""
import numpy as np
from hexcal.io.table_writing import FORMAT_ROWS, format_rows
with open(out, "wb") as fh:
    for k in range(0, len(data), FORMAT_ROWS):
        fh.write(format_rows(out, data[k : k + FORMAT_ROWS]))
""",
    "pyarrow.csv.write_csv (write)": r"""
import pyarrow as pa
import pyarrow.csv as pc
pc.write_csv(pa.table({c: data[:, k] for k, c in enumerate("xyzabc")}), out)
""",
}

CHILD = r"""
import json, os, sys, time
path, out, threads, case = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
os.environ["POLARS_MAX_THREADS"] = str(threads)
code = json.loads(sys.argv[5])
data = None
if "(write)" in case:
    import numpy as np
    data = np.loadtxt(path, delimiter=",", usecols=range(1, 7), skiprows=1, comments=None, ndmin=2)
start, wall = time.process_time(), time.perf_counter()
scope = {"path": path, "out": out, "threads": threads, "data": data}
try:
    exec(code, scope)
except ImportError as error:
    print(json.dumps({"missing": str(error)}))
    raise SystemExit(0)
cpu, wall = time.process_time() - start, time.perf_counter() - wall
values = scope.get("values")
shape = None if values is None else list(values.shape)
print(json.dumps({"cpu": cpu, "wall": wall, "shape": shape}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rows", type=int, default=1_000_000)
    args = parser.parse_args()
    import json

    src = str(Path(__file__).resolve().parents[1] / "src")
    env = dict(os.environ, PYTHONPATH=src + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.setdefault("OPENBLAS_NUM_THREADS", "1")
    cores = os.cpu_count() or 1
    print(f"{args.rows:,} pose rows; {cores} core(s); load average {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as folder:
        path, out = str(Path(folder) / "poses.csv"), str(Path(folder) / "out.csv")
        subprocess.run([sys.executable, "-c", MAKE, path, str(args.rows)], env=env, check=True)
        for threads in sorted({1, cores}):
            base: dict[str, float] = {}
            print(f"\n{threads} thread(s): CPU s (wall s), ratio to numpy's reader / hexcal's writer")
            for name, code in CASES.items():
                done = subprocess.run(
                    [sys.executable, "-c", CHILD, path, out, str(threads), name, json.dumps(code)],
                    env=env, capture_output=True, text=True, check=True,
                )  # fmt: skip
                result = json.loads(done.stdout.strip().splitlines()[-1])
                if "missing" in result:
                    print(f"  {name:36s} not installed ({result['missing']})")
                    continue
                kind = "write" if "(write)" in name else "read"
                base.setdefault(kind, result["cpu"])
                print(
                    f"  {name:36s} {result['cpu']:6.3f} ({result['wall']:6.3f})"
                    f"  {result['cpu'] / base[kind]:5.2f}x the CPU of the first {kind}"
                )


if __name__ == "__main__":
    main()
