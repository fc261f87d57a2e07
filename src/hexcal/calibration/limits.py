"""The verdict's and validation's limits and defaults, in one place, for Python and the command
line alike.

Every threshold of the verdict (:mod:`hexcal.calibration.verdict` and the modules that find its
reasons) is here, with what it means; ``hexcal identify`` shows them as its options' defaults
and decides nothing of its own. Standard library only (the command line's help reads them
without numpy).

>>> SIGMA_LIMIT, MAX_CHANGE
(0.2, 0.25)
"""

#: The identifiability limit, as a fraction of the platform radius: a parameter combination
#: whose predicted σ exceeds it is poorly determined (``warn``), beyond :data:`FAIL_FACTOR`
#: times it not determined (``fail``); gains: 1e-3 (relative) per mm of it, instrument angles
#: 1e-3 rad per mm.
SIGMA_LIMIT = 0.2

#: A combination whose predicted σ exceeds the limit is poorly determined (``warn``); beyond
#: this many times the limit it is not determined at all (``fail``).
FAIL_FACTOR = 3.0

#: Largest plausible change of a parameter, as a fraction of the machine's size (base radius
#: for ``u``, platform radius for ``s``, the larger for ``l0``; of the gain for gains): beyond
#: it, ``fail``.
MAX_CHANGE = 0.25

#: Robust σ beyond which a pose's leg residual is an outlier (``warn``) ...
SCREEN_THRESHOLD = 8.0
#: ... and this many times that, a gross error (``fail``).
GROSS_FACTOR = 5.0

#: A learned σ more than this many times its reference (the σ a setup declares, else the most
#: that instruments of its kind show) means the model does not describe the data: ``warn``
#: (:mod:`hexcal.calibration.noise_judgement`) ...
MODEL_ERROR_FACTOR = 3.0
#: ... and more than this many times the most such instruments show: ``fail``.
MODEL_ERROR_FAIL = 10.0

#: Level of the test for steps and drifts in each session's acquisition order (all families,
#: all split points together; :mod:`hexcal.calibration.sequence`).
SEQUENCE_ALPHA = 1e-3
#: A step or drift that would shrink the learned noise by more than this factor (it explains
#: more than 1 - 1/1.5² = 56 % of the residuals) is a ``fail`` ...
FAIL_INFLATION = 1.5
#: ... one that explains at least this share of the residuals a ``warn``, a smaller one (found,
#: but a small part of what the fit leaves, as beside a model error that follows the poses) an
#: ``info``.
WARN_SHARE = 0.1
#: The fewest observations on either side of a step.
MIN_SEGMENT = 5

# -- validation (:mod:`hexcal.calibration.validation`, :mod:`hexcal.workflow.validation`) ----

#: Folds of validate's cross-validated re-registration of an instrument's free quantities.
VALIDATION_FOLDS = 5

#: Default tolerance (mm) on every leg reading for two observations to be visits of one
#: commanded pose (ISO 9283: :mod:`hexcal.calibration.iso_poses`) ...
VISIT_TOLERANCE = 0.01
#: ... and the largest. Visits of one pose read the same leg commands, to the file's rounding or
#: a servo's error (micrometres); legs a tenth of a millimetre apart command another pose, and
#: grouping them would report the distance between poses as repeatability (a tolerance of 1e9
#: made 20 poses one, RP 368 mm).
VISIT_TOLERANCE_LIMIT = 0.1
