"""robustctl.correlate (see DESIGN.md)."""
