"""Find the package's data files (models, parameter files) in a checkout or an install."""

from pathlib import Path
import sys

PACKAGE_NAME = 'followbot'


def share_file(folder: str, name: str) -> Path:
    """
    Find a data file of the package, from a source checkout or an install.

    A source checkout (or an editable install) has the data folders beside the Python
    packages; an installed package (colcon, or pip into a prefix) has them in
    ``share/followbot/<folder>``, found through the ament index when the workspace is sourced,
    else under ``sys.prefix``.

    :param folder: the data folder, such as ``models`` or ``config``.
    :param name: the file's name in that folder.
    :return: the path of the file.
    :raises FileNotFoundError: if no candidate folder holds the file.
    """
    candidates = [Path(__file__).resolve().parent.parent / folder]
    try:
        from ament_index_python.packages import get_package_share_directory
        candidates.append(Path(get_package_share_directory(PACKAGE_NAME)) / folder)
    except (ImportError, LookupError, OSError):
        pass  # No ament index holds this package: not a sourced ROS install.
    candidates.append(Path(sys.prefix) / 'share' / PACKAGE_NAME / folder)
    for candidate in candidates:
        if (candidate / name).is_file():
            return candidate / name
    searched = ', '.join(str(path) for path in candidates)
    raise FileNotFoundError(f'No {folder}/{name} found for {PACKAGE_NAME}; looked in: '
                            f'{searched}.')
