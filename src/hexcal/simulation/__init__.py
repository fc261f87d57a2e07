"""Monte Carlo simulation of calibration campaigns: one campaign protocol
(:mod:`~hexcal.simulation.protocol`: trial seeds, true machines, simulated data,
validation; :mod:`~hexcal.simulation.identify`: identification and bounds), one runner
that maps chunks of trials over an executor (:mod:`~hexcal.simulation.runner`), and the
seed paper's experiment (:mod:`~hexcal.simulation.paper`) and the studies
(:mod:`~hexcal.simulation.study`) as definitions over them. Imports every layer below
(core to design).

Public names
------------
- ``simulate_session``, ``simulate_measurements``: one simulated session of any instrument
  (or full-pose measurements) of a true machine at commanded poses.
- ``simulate_campaigns``, ``CampaignData``, ``TrialSeeds``, ``random_machines``,
  ``true_machines``: many simulated campaigns, seeded per trial.
- ``run_paper_experiment``, ``PaperExperiment``, ``PAPER_TABLE1``, ``PAPER_VALIDATION``: the
  seed paper's Table I by Monte Carlo.
- ``run_study``, ``StudyDefinition``, ``StudyResult``, ``StudyCell``, ``STRATEGIES``,
  ``PoseStrategy``, ``FixedStrategy``, ``fixed_strategy``, ``InstrumentCampaign``,
  ``instrument_campaign``: studies of calibration strategies (``hexcal simulate``).
- ``SerialExecutor``, ``DaskExecutor``, ``Executor``, ``Progress``: where the trials run.
- ``warm_up``, ``constant_temperature``, ``payload_cases``: the conditions of a simulated
  campaign (the legs' temperatures, the payloads), for ``simulate_session(covariates=...)``.

Other names of the lazy map below (chunk functions, batch definitions, the runner's
internals) are not part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "BatchDefinition": "identify",
    "CHUNKS": "runner",
    "CampaignData": "protocol",
    "ChunkFunction": "runner",
    "DaskExecutor": "dask_executor",
    "Executor": "runner",
    "FixedStrategy": "study",
    "InstrumentCampaign": "instrument_trials",
    "MAX_CHUNK": "runner",
    "MachineBatch": "protocol",
    "PAPER_TABLE1": "paper",
    "PAPER_VALIDATION": "paper",
    "PaperDefinition": "paper",
    "PaperExperiment": "paper",
    "PoseStrategy": "study",
    "Progress": "runner",
    "ROW_LABELS": "paper",
    "STRATEGIES": "study",
    "SerialExecutor": "runner",
    "StudyCell": "study",
    "StudyDefinition": "study",
    "StudyResult": "study",
    "TrialSeeds": "protocol",
    "campaign_bounds": "identify",
    "constant_temperature": "conditions",
    "payload_cases": "conditions",
    "warm_up": "conditions",
    "chunk_indices": "runner",
    "dask_executor": "dask_executor",
    "default_chunk_size": "runner",
    "fixed_strategy": "study",
    "identify_batch": "identify",
    "identify_chunk": "identify",
    "identify_or_nan": "identify",
    "identify_trials": "identify",
    "instrument_campaign": "instrument_trials",
    "map_trials": "runner",
    "paper_trials": "paper",
    "random_machines": "protocol",
    "resolve_jobs": "runner",
    "run_paper_experiment": "paper",
    "run_study": "study",
    "simulate_campaigns": "protocol",
    "simulate_measurements": "protocol",
    "simulate_session": "protocol",
    "study_trials": "study",
    "true_machines": "protocol",
    "validate": "protocol",
}

__all__ = [
    "PAPER_TABLE1",
    "PAPER_VALIDATION",
    "STRATEGIES",
    "CampaignData",
    "DaskExecutor",
    "Executor",
    "FixedStrategy",
    "InstrumentCampaign",
    "PaperExperiment",
    "PoseStrategy",
    "Progress",
    "SerialExecutor",
    "StudyCell",
    "StudyDefinition",
    "StudyResult",
    "TrialSeeds",
    "constant_temperature",
    "fixed_strategy",
    "instrument_campaign",
    "payload_cases",
    "random_machines",
    "run_paper_experiment",
    "run_study",
    "simulate_campaigns",
    "simulate_measurements",
    "simulate_session",
    "true_machines",
    "warm_up",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
