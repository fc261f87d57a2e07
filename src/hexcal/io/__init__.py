"""Reading and writing hexcal's files (docs/formats.md): geometry and setup YAML, CSV tables,
sessions, LinuxCNC configurations and G-code programs.

Every reader validates strictly and raises :class:`InputError` with one line that
names the file, the line and the column of the problem. Every writer writes to a
temporary file in the target's folder and renames it, so that an output file is
either complete or absent. Input files are only ever opened for reading.

Modules: :mod:`~hexcal.io.outputs` (:class:`OutputSet`: a command's outputs checked up
front, staged and committed all together), :mod:`~hexcal.io.inputs` (regular files only,
row limits, YAML with limits), :mod:`~hexcal.io.files` (atomic writes, JSON),
:mod:`~hexcal.io.geometry_file` (YAML geometries), :mod:`~hexcal.io.tables` (the table model:
rows as text, decimal marks, column names and maps), :mod:`~hexcal.io.table_fast` (blocks of
plain rows converted whole by numpy), :mod:`~hexcal.io.measurement_files` (the
one reader of every table, whole or in blocks: delimiter, unit row, limits; pose, measurement
and leg files), :mod:`~hexcal.io.table_writing` (writing tables), :mod:`~hexcal.io.target_files`
(instrument exports, column maps from a command line, covariance matrices),
:mod:`~hexcal.io.covariate_columns` (the covariate columns of any table: time, leg
temperatures, payload), :mod:`~hexcal.io.sessions` (the readers and writers of each
instrument's data),
:mod:`~hexcal.io.gcode` (G-code programs, read and written in blocks).
Imports every layer below it; only ``io`` and ``cli`` touch files.

Public names
------------
- ``load_geometry``, ``save_geometry``: geometry files (docs/formats.md "Geometry file") or
  presets by name.
- ``load_setup``, ``save_setup``: setup files (docs/formats.md "Setup file").
- ``read_session``, ``read_sessions``, ``write_session_data``, ``load_instrument``,
  ``READERS``, ``WRITERS``: a session from a data file and its setup, whatever the
  instrument (docs/formats.md "Sessions").
- ``read_measurements``, ``write_measurements``, ``read_target_measurements``,
  ``write_target_measurements``, ``read_tool_measurements``: measurement files of each
  instrument (docs/formats.md "Measurement file", "Target measurement file").
- ``read_poses``, ``write_poses``, ``iter_poses``, ``read_legs``, ``write_legs``, ``iter_legs``,
  ``LegData``: pose and leg files, whole or in blocks (docs/formats.md "Pose file", "Leg file").
- ``read_table``, ``Table``, ``COLUMN_NAMES``, ``parse_column_map``, ``DEFAULT_MAX_ROWS``,
  ``MEASUREMENT_MAX_ROWS``: any table by hexcal's one reader (docs/formats.md "Tables"),
  column maps and row limits.
- ``read_matrix``: a pose covariance file (six rows of six numbers).
- ``write_json``: strict JSON, written atomically.
- ``import_linuxcnc``, ``export_linuxcnc``: LinuxCNC genhexkins configurations.
- ``read_program``: G-code programs in blocks (``hexcal compensate --gcode``).

Other names of the lazy map below (output sets, atomic writes, YAML limits, the table
scanner's pieces, LinuxCNC and G-code details) are shared with the command line and are not
part of the API.
"""

from hexcal._lazy import attach

_NAMES = {
    "BLOCK_ROWS": "tables",
    "COLUMN_NAMES": "tables",
    "DEFAULT_MAX_ROWS": "inputs",
    "DEGREE_SUSPICION": "measurement_files",
    "DELIMITERS": "tables",
    "GENHEXKINS_DEFAULT_BASE": "linuxcnc",
    "GENHEXKINS_DEFAULT_PLATFORM": "linuxcnc",
    "HAL_FILE": "linuxcnc",
    "HalSettings": "linuxcnc_import",
    "INI_FILE": "linuxcnc",
    "IniFile": "linuxcnc_import",
    "LEG_LENGTH_COLUMNS": "tables",
    "LEG_READING_COLUMNS": "tables",
    "LINUXCNC_EULER": "linuxcnc",
    "LegData": "measurement_files",
    "LimitedSafeLoader": "inputs",
    "LinuxCNCFormatError": "linuxcnc",
    "MAX_FIELD_CHARS": "tables",
    "MAX_YAML_BYTES": "inputs",
    "MAX_YAML_DEPTH": "inputs",
    "MAX_YAML_NODES": "inputs",
    "MEASUREMENT_MAX_ROWS": "inputs",
    "ORIENTATION_GROUPS": "tables",
    "OutputError": "outputs",
    "OutputSet": "outputs",
    "ProgramBlock": "gcode",
    "ProgramWriter": "gcode",
    "QUATERNION_NORM_TOLERANCE": "measurement_files",
    "READERS": "sessions",
    "STDOUT": "outputs",
    "Table": "tables",
    "TableWriter": "table_writing",
    "UNIT_WORDS": "tables",
    "WRITERS": "sessions",
    "YamlLimitError": "inputs",
    "active_outputs": "outputs",
    "atomic_write": "files",
    "check_column_map": "tables",
    "check_input": "inputs",
    "euler_warning": "linuxcnc",
    "export_linuxcnc": "linuxcnc",
    "gcode_comment": "gcode",
    "import_linuxcnc": "linuxcnc_import",
    "iter_legs": "measurement_files",
    "iter_poses": "measurement_files",
    "iter_tables": "table_reading",
    "load_geometry": "geometry_file",
    "load_instrument": "sessions",
    "load_setup": "setup_file",
    "load_yaml": "inputs",
    "open_input": "inputs",
    "output_file": "outputs",
    "parse_column_map": "target_files",
    "parse_hal": "linuxcnc_import",
    "parse_ini": "linuxcnc_import",
    "plain": "files",
    "read_export": "target_files",
    "read_legs": "measurement_files",
    "read_matrix": "target_files",
    "read_measurements": "measurement_files",
    "read_poses": "measurement_files",
    "read_program": "gcode",
    "read_session": "sessions",
    "read_sessions": "sessions",
    "read_table": "table_reading",
    "read_target_measurements": "target_files",
    "read_text": "inputs",
    "read_tool_measurements": "target_files",
    "save_geometry": "geometry_file",
    "save_setup": "setup_file",
    "save_setup_dict": "sessions",
    "table_covariates": "covariate_columns",
    "table_legs": "measurement_files",
    "table_poses": "measurement_files",
    "too_many_rows": "inputs",
    "write_json": "files",
    "write_legs": "table_writing",
    "write_measurements": "table_writing",
    "write_poses": "table_writing",
    "write_session_data": "sessions",
    "write_table": "table_writing",
    "write_table_blocks": "table_writing",
    "write_target_measurements": "target_files",
    "write_text": "files",
}

__all__ = [
    "COLUMN_NAMES",
    "DEFAULT_MAX_ROWS",
    "MEASUREMENT_MAX_ROWS",
    "READERS",
    "WRITERS",
    "LegData",
    "Table",
    "export_linuxcnc",
    "import_linuxcnc",
    "iter_legs",
    "iter_poses",
    "load_geometry",
    "load_instrument",
    "load_setup",
    "parse_column_map",
    "read_legs",
    "read_matrix",
    "read_measurements",
    "read_poses",
    "read_program",
    "read_session",
    "read_sessions",
    "read_table",
    "read_target_measurements",
    "read_tool_measurements",
    "save_geometry",
    "save_setup",
    "write_json",
    "write_legs",
    "write_measurements",
    "write_poses",
    "write_session_data",
    "write_target_measurements",
]

__getattr__, _dir, _names = attach(__name__, _NAMES)


def __dir__() -> list[str]:
    return sorted(__all__)
