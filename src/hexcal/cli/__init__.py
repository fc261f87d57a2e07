"""The ``hexcal`` command line: thin subcommands over the library, one module per group.

- :mod:`hexcal.cli.main`: the parser and :func:`main` (the console script);
- :mod:`hexcal.cli.common`: shared option helpers and :class:`CommandError`;
- :mod:`hexcal.cli.noise`: the noise options (``--noise``, ``--noise-dist``, ``--pose-covariance``);
- :mod:`hexcal.cli.kinematics` (preset, ik, fk), :mod:`hexcal.cli.calibrate` (identify,
  validate, synthesize), :mod:`hexcal.cli.compensation` (compensate),
  :mod:`hexcal.cli.simulate` (simulate, paper),
  :mod:`hexcal.cli.plan` (errormap, observability, candidates, select).

The top of every module imports only the standard library, :mod:`hexcal.errors`,
:mod:`hexcal.cli.common` and :mod:`hexcal.cli.noise`; a command imports the library when it runs, so that
``hexcal --help`` loads no numpy. The CLI may import every layer; no layer imports it.
"""

# ``main`` names the function, not the submodule: importing the submodule first and then
# binding the name keeps the package attribute the function (the console script's target).
from hexcal.cli.common import CommandError
from hexcal.cli.main import build_parser, main
from hexcal.cli.noise import parse_noise

__all__ = ["CommandError", "build_parser", "main", "parse_noise"]
