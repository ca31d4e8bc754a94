"""Primitive -> PointCloud constructors (paper §3.1): being written."""
