"""Files: H5MD trajectories and restart files."""

SCHEMA_VERSION = 2
"""Version of revdem's layout inside H5MD trajectories and restart files."""


def open_hdf5(path):
    """Open an HDF5 file for reading; InputError naming the file if it is not one."""
    from pathlib import Path

    import h5py

    from revdem_cli.errors import InputError

    try:
        return h5py.File(Path(path), "r")
    except OSError:
        raise InputError(f"{path}: not a readable HDF5 file") from None
