"""Reading and writing hexcal's files (FORMATS.md): geometry YAML and CSV tables.

Every reader validates strictly and raises :class:`InputError` with one line that
names the file, the line and the column of the problem. Every writer writes to a
temporary file in the target's folder and renames it, so that an output file is
either complete or absent. Input files are only ever opened for reading.

Modules: :mod:`~hexcal.io.outputs` (:class:`OutputSet`: a command's outputs checked up
front, staged and committed all together), :mod:`~hexcal.io.inputs` (regular files only,
row limits, YAML with limits), :mod:`~hexcal.io.files` (atomic writes, JSON),
:mod:`~hexcal.io.geometry_file` (YAML geometries), :mod:`~hexcal.io.tables` (CSV, whole or in
blocks), :mod:`~hexcal.io.measurement_files` (pose, measurement and leg files).
Imports every layer below it; only ``io`` and ``cli`` touch files.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "BLOCK_ROWS": "tables",
        "DEFAULT_MAX_ROWS": "inputs",
        "DEGREE_SUSPICION": "measurement_files",
        "MAX_YAML_DEPTH": "inputs",
        "MEASUREMENT_MAX_ROWS": "inputs",
        "MAX_YAML_NODES": "inputs",
        "OutputError": "outputs",
        "OutputSet": "outputs",
        "STDOUT": "outputs",
        "TableWriter": "table_writing",
        "active_outputs": "outputs",
        "check_input": "inputs",
        "iter_legs": "measurement_files",
        "iter_poses": "measurement_files",
        "iter_tables": "tables",
        "load_yaml": "inputs",
        "open_input": "inputs",
        "output_file": "outputs",
        "table_legs": "measurement_files",
        "write_json": "files",
        "write_table_blocks": "table_writing",
        "write_text": "files",
        "LEG_LENGTH_COLUMNS": "measurement_files",
        "LEG_READING_COLUMNS": "measurement_files",
        "LegData": "measurement_files",
        "ORIENTATION_GROUPS": "measurement_files",
        "QUATERNION_NORM_TOLERANCE": "measurement_files",
        "Table": "tables",
        "atomic_write": "files",
        "load_geometry": "geometry_file",
        "plain": "files",
        "read_legs": "measurement_files",
        "read_matrix": "tables",
        "read_measurements": "measurement_files",
        "read_poses": "measurement_files",
        "read_table": "tables",
        "save_geometry": "geometry_file",
        "table_poses": "measurement_files",
        "write_legs": "measurement_files",
        "write_measurements": "measurement_files",
        "write_poses": "measurement_files",
        "write_table": "table_writing",
    },
)
