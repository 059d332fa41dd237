"""Files: writing that never destroys what was there, and bounded reading of YAML."""
