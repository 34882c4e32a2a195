"""Built-in world files (YAML); ``envs/`` at the repository top level links here."""
