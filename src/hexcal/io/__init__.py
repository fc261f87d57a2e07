"""Reading and writing hexcal's files (FORMATS.md): geometry YAML and CSV tables.

Every reader validates strictly and raises :class:`InputError` with one line that
names the file, the line and the column of the problem. Every writer writes to a
temporary file in the target's folder and renames it, so that an output file is
either complete or absent. Input files are only ever opened for reading.

Modules: :mod:`~hexcal.io.outputs` (:class:`OutputSet`: a command's outputs checked up
front, staged and committed all together), :mod:`~hexcal.io.inputs` (regular files only,
row limits, YAML with limits), :mod:`~hexcal.io.files` (atomic writes, JSON),
:mod:`~hexcal.io.geometry_file` (YAML geometries), :mod:`~hexcal.io.tables` (the table model:
rows as text, decimal marks, column names and maps), :mod:`~hexcal.io.measurement_files` (the
one reader of every table, whole or in blocks: delimiter, unit row, limits; pose, measurement
and leg files), :mod:`~hexcal.io.table_writing` (writing tables), :mod:`~hexcal.io.target_files`
(instrument exports, column maps from a command line, covariance matrices).
Imports every layer below it; only ``io`` and ``cli`` touch files.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "BLOCK_ROWS": "tables",
        "DEFAULT_MAX_ROWS": "inputs",
        "DEGREE_SUSPICION": "measurement_files",
        "COLUMN_NAMES": "tables",
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
        "QUATERNION_NORM_TOLERANCE": "measurement_files",
        "STDOUT": "outputs",
        "Table": "tables",
        "TableWriter": "table_writing",
        "UNIT_WORDS": "tables",
        "YamlLimitError": "inputs",
        "active_outputs": "outputs",
        "atomic_write": "files",
        "check_column_map": "tables",
        "check_input": "inputs",
        "euler_warning": "linuxcnc",
        "export_linuxcnc": "linuxcnc",
        "import_linuxcnc": "linuxcnc_import",
        "iter_legs": "measurement_files",
        "iter_poses": "measurement_files",
        "iter_tables": "measurement_files",
        "load_geometry": "geometry_file",
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
        "read_table": "measurement_files",
        "read_target_measurements": "target_files",
        "read_text": "inputs",
        "read_tool_measurements": "target_files",
        "save_geometry": "geometry_file",
        "save_setup": "setup_file",
        "table_legs": "measurement_files",
        "table_poses": "measurement_files",
        "too_many_rows": "inputs",
        "write_json": "files",
        "write_legs": "table_writing",
        "write_measurements": "table_writing",
        "write_poses": "table_writing",
        "write_table": "table_writing",
        "write_table_blocks": "table_writing",
        "write_target_measurements": "target_files",
        "write_text": "files",
    },
)
