"""Pepper perception: organised point clouds, the detector, 3D fruit points."""
