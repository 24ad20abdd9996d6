"""The missions shipped with taskflow (YAML files), installed as the package ``taskflow_missions``.

``taskflow run`` with no file runs :data:`DEFAULT` from here, also when taskflow is installed from a
wheel rather than from a checkout.
"""

from pathlib import Path

DIR = Path(__file__).resolve().parent
DEFAULT = DIR / "car_waypoints.yaml"
