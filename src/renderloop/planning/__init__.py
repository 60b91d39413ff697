"""Scan waypoints, collision-free transits and the TOPP-RA trajectory."""
