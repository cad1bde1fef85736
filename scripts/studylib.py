"""What the study scripts (study-rates.py, study-realism.py) share."""

import json


def toml_text(v):
    """A TOML value as `vinebench sweep` prints it in a run's `point` (and as TOML reads it
    back): `2`, `0.5`, `"dense"`, `[3.0, 1.5]`, `true`."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(toml_text(x) for x in v) + "]"
    if isinstance(v, str):
        return json.dumps(v)
    return repr(v)
