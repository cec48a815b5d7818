"""bicoord-drake: the BiCoord bimanual manipulation benchmark on Drake."""

__version__ = "0.1.0"
