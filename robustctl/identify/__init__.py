"""robustctl.identify (see DESIGN.md)."""
