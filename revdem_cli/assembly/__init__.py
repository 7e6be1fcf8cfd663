"""Initial states: generated packings of spheres."""
