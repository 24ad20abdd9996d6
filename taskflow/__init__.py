"""taskflow: robot missions written as YAML hierarchical state machines, run on PyBullet."""

__version__ = "0.1.0"
