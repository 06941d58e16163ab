"""robustctl.robust (see DESIGN.md)."""
