"""Several UAVs sharing a compartment's scan: one mission a row."""
