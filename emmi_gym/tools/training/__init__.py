"""Training SB3 agents from configurations, evaluating them, and the reward benchmark (needs the
``train`` extra: Stable-Baselines3, sb3-contrib, torch)."""
