"""Simulated instruments: each is a SCPI device (``sim.scpi``) that is a view of the World."""
