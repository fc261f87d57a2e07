"""Monte Carlo simulation of calibration campaigns: one campaign protocol
(:mod:`~hexcal.simulation.protocol`: trial seeds, true machines, simulated data,
validation; :mod:`~hexcal.simulation.identify`: identification and bounds), one runner
that maps chunks of trials over an executor (:mod:`~hexcal.simulation.runner`), and the
seed paper's experiment (:mod:`~hexcal.simulation.paper`) and the studies
(:mod:`~hexcal.simulation.study`) as definitions over them. Imports every layer below
(core to design).
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "BatchDefinition": "identify",
        "CHUNKS": "runner",
        "CampaignData": "protocol",
        "DaskExecutor": "dask_executor",
        "ChunkFunction": "runner",
        "Executor": "runner",
        "FixedStrategy": "study",
        "InstrumentCampaign": "instrument_trials",
        "instrument_campaign": "instrument_trials",
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
        "chunk_indices": "runner",
        "dask_executor": "dask_executor",
        "default_chunk_size": "runner",
        "fixed_strategy": "study",
        "identify_batch": "identify",
        "identify_chunk": "identify",
        "identify_or_nan": "identify",
        "identify_trials": "identify",
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
    },
)
