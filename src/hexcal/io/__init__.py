"""Reading and writing hexcal's files (FORMATS.md): geometry YAML and CSV tables.

Every reader validates strictly and raises :class:`InputError` with one line that
names the file, the line and the column of the problem. Every writer writes to a
temporary file in the target's folder and renames it, so that an output file is
either complete or absent. Input files are only ever opened for reading.

Modules: :mod:`~hexcal.io.files` (atomic writes), :mod:`~hexcal.io.geometry_file` (YAML
geometries), :mod:`~hexcal.io.tables` (CSV), :mod:`~hexcal.io.measurement_files` (pose,
measurement and leg files). Imports every layer below it; only ``io`` and ``cli`` touch files.
"""

from hexcal._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "DEGREE_SUSPICION": "measurement_files",
        "DELIMITERS": "target_files",
        "GENHEXKINS_DEFAULT_BASE": "linuxcnc",
        "GENHEXKINS_DEFAULT_PLATFORM": "linuxcnc",
        "HAL_FILE": "linuxcnc",
        "HalSettings": "linuxcnc_import",
        "INI_FILE": "linuxcnc",
        "IniFile": "linuxcnc_import",
        "LEG_LENGTH_COLUMNS": "measurement_files",
        "LEG_READING_COLUMNS": "measurement_files",
        "LINUXCNC_EULER": "linuxcnc",
        "LegData": "measurement_files",
        "LinuxCNCFormatError": "linuxcnc",
        "ORIENTATION_GROUPS": "measurement_files",
        "QUATERNION_NORM_TOLERANCE": "measurement_files",
        "Table": "tables",
        "UNIT_WORDS": "target_files",
        "atomic_write": "files",
        "euler_warning": "linuxcnc",
        "export_linuxcnc": "linuxcnc",
        "import_linuxcnc": "linuxcnc_import",
        "load_geometry": "geometry_file",
        "load_setup": "setup_file",
        "parse_hal": "linuxcnc_import",
        "parse_ini": "linuxcnc_import",
        "plain": "files",
        "read_export": "target_files",
        "read_legs": "measurement_files",
        "read_matrix": "tables",
        "read_measurements": "measurement_files",
        "read_poses": "measurement_files",
        "read_table": "tables",
        "read_target_measurements": "target_files",
        "read_tool_measurements": "target_files",
        "save_geometry": "geometry_file",
        "save_setup": "setup_file",
        "table_poses": "measurement_files",
        "write_legs": "measurement_files",
        "write_measurements": "measurement_files",
        "write_poses": "measurement_files",
        "write_table": "tables",
        "write_target_measurements": "target_files",
    },
)
