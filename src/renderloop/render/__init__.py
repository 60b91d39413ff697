"""RGB-D rendering at the flown camera poses: camera model, Cycles and raster backends, executors."""
