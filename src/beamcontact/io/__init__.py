"""Files in and out: case schema, results writers (CSV, JSON, HDF5, VTU/PVD)."""
