"""Geometry shared by the locator, the simulator and the studies: PnP solves and projection,
and the geometry of a fixture's disc."""
