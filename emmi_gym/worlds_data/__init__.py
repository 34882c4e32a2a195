"""Built-in world files (YAML), shipped in the package."""
