"""Yield estimation: OPTICS counting of the 3D fruit detections per row, scoring against scene.json, the harvest plan."""
