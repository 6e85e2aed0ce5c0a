"""Simulation: rolling-shutter photographs of a room, chessboard photos, whole surveys."""
