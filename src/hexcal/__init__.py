"""hexcal: kinematic calibration of hexapods (Stewart-Gough platforms, hexapod machine tools)."""

import os as _os

# hexcal's linear algebra is many small matrices (6x6 blocks, 90x42 Jacobians), for which
# OpenBLAS's threads cost far more than they give: on a busy 2-core machine one 15-pose
# identification took 19 ms with threads and 2 ms without. Only a default: an explicit
# setting wins, and it has no effect if numpy was imported before hexcal.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    _os.environ.setdefault(_var, "1")

__version__ = "0.1.0"
