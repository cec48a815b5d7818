"""Episode data: HDF5 episode files, readers for our and other benchmarks' layouts, exports."""
