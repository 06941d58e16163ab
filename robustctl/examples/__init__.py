"""robustctl.examples (see DESIGN.md)."""
