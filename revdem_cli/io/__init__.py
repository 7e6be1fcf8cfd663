"""Files: H5MD trajectories and restart files."""

SCHEMA_VERSION = 2
"""Version of revdem's layout inside H5MD trajectories and restart files."""
