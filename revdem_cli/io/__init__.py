"""Files: H5MD trajectories and restart files."""

SCHEMA_VERSION = 1
"""Version of revdem's layout inside H5MD trajectories and restart files."""
