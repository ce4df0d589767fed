"""The framework: bench clock, run store, unit specs, site, the procedure runner."""
