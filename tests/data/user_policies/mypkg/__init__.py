"""A user's own package next to where they run ``wfbench`` (found through the current folder)."""
