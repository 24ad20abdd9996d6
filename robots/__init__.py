"""Robot descriptions: kinematic parameters, limits, sensor mounts (no simulator code)."""
