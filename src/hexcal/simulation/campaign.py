"""Former home of the simulated campaign, kept so that old imports keep working.

The protocol is now in :mod:`hexcal.simulation.protocol` and
:mod:`hexcal.simulation.identify`, the runner in :mod:`hexcal.simulation.runner` and the
seed paper's experiment in :mod:`hexcal.simulation.paper`; import these names from
:mod:`hexcal.simulation`. This module goes once no importer is left.
"""

from hexcal.simulation.identify import identify_batch
from hexcal.simulation.paper import PaperExperiment, run_paper_experiment
from hexcal.simulation.protocol import MachineBatch, pose_errors, random_machines, simulate_measurements
from hexcal.simulation.runner import Progress

__all__ = [
    "MachineBatch",
    "PaperExperiment",
    "Progress",
    "identify_batch",
    "pose_errors",
    "random_machines",
    "run_paper_experiment",
    "simulate_measurements",
]
