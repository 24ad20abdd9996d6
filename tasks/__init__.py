"""Control laws: pure numpy/Pinocchio functions and the registered tasks built on them (no PyBullet)."""
