"""The Drake diagram: station, control systems, cameras, stepping."""
