"""Hand-over to and from geomdl: curve objects and geomdl's JSON exchange layout.

geomdl's ``exchange.export_json`` writes ``{"shape": {"type": "curve", "count": k, "data":
[curve, ...]}}`` with each curve as ``{"type": "spline", "rational", "dimension", "degree",
"knotvector", "control_points": {"points": Cartesian points, "weights"}, "delta"}``, and
``exchange.import_json`` reads ``degree``, ``knotvector``, ``control_points.points`` and the
optional ``weights`` of each curve, ignoring other keys. primlib writes that layout and puts
the duration beside the shape, as the top-level key ``"duration"`` (seconds), so geomdl still
reads the file.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from primlib._errors import InputError

__all__ = ["to_geomdl", "definition_from_geomdl", "exchange_dict", "definition_from_exchange"]


def to_geomdl(degree: int, knots: np.ndarray, ctrlpts: np.ndarray, weights: np.ndarray):
    """Build a geomdl ``NURBS.Curve`` (parameter = normalised time) from a definition."""
    from geomdl import NURBS

    curve = NURBS.Curve()
    curve.degree = int(degree)
    curve.ctrlpts = ctrlpts.tolist()
    curve.weights = weights.tolist()
    curve.knotvector = knots.tolist()
    return curve


def definition_from_geomdl(curve: Any) -> dict:
    """Degree, knots, Cartesian control points and weights of a geomdl curve.

    Raises
    ------
    InputError
        If ``curve`` is not a geomdl curve with control points and a knot vector.
    """
    try:
        degree = int(curve.degree)
        knots = np.asarray(curve.knotvector, dtype=np.float64)
        ctrlpts = np.asarray(curve.ctrlpts, dtype=np.float64)
        weights = getattr(curve, "weights", None)
    except (AttributeError, TypeError, ValueError):
        raise InputError(
            f"curve: expected a geomdl BSpline.Curve or NURBS.Curve, got {type(curve).__name__}"
        ) from None
    if weights is None or len(weights) == 0:
        weights = np.ones(ctrlpts.shape[0])
    return dict(
        degree=degree,
        knots=knots,
        ctrlpts=ctrlpts,
        weights=np.asarray(weights, dtype=np.float64),
    )


def exchange_dict(
    degree: int, knots: np.ndarray, ctrlpts: np.ndarray, weights: np.ndarray, duration: float
) -> dict:
    """geomdl's JSON exchange layout for one curve, with ``"duration"`` beside the shape."""
    curve = {
        "type": "spline",
        "rational": True,
        "dimension": int(ctrlpts.shape[1]),
        "degree": int(degree),
        "knotvector": knots.tolist(),
        "control_points": {"points": ctrlpts.tolist(), "weights": weights.tolist()},
        "delta": 0.01,
    }
    return {"shape": {"type": "curve", "count": 1, "data": [curve]}, "duration": float(duration)}


def definition_from_exchange(data: Any, source: str, duration: float | None = None) -> dict:
    """Definition (with duration) from a parsed geomdl JSON exchange document.

    Parameters
    ----------
    data : object
        The parsed JSON.
    source : str
        Where it came from (a file name), for error messages.
    duration : float, optional
        Duration in seconds, used only when the document has no ``"duration"`` key (a
        plain geomdl file).

    Raises
    ------
    InputError
        If the document is not one geomdl curve, or there is no duration.
    """
    try:
        shape = data["shape"]
        kind = shape["type"]
        curves = shape["data"]
    except (KeyError, TypeError):
        raise InputError(
            f"{source}: expected geomdl JSON with a 'shape' holding 'type' and 'data'"
        ) from None
    if kind != "curve":
        raise InputError(f"{source}: expected a geomdl curve, got shape type {kind!r}")
    if not isinstance(curves, list) or len(curves) != 1:
        count = len(curves) if isinstance(curves, list) else type(curves).__name__
        raise InputError(f"{source}: expected exactly one curve, got {count}")
    curve = curves[0]
    try:
        degree = curve["degree"]
        knots = np.asarray(curve["knotvector"], dtype=np.float64)
        points = np.asarray(curve["control_points"]["points"], dtype=np.float64)
        weights = curve["control_points"].get("weights")
        weights = (
            np.ones(points.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
        )
    except (KeyError, TypeError, ValueError, AttributeError):
        raise InputError(
            f"{source}: expected a curve with 'degree', 'knotvector' and numeric "
            "'control_points.points'"
        ) from None
    stored = data.get("duration") if isinstance(data, dict) else None
    if stored is None:
        stored = duration
    if stored is None:
        raise InputError(
            f"{source}: expected a 'duration' (seconds) beside the curve, got none; "
            "pass duration= for a plain geomdl file"
        )
    if not isinstance(degree, int) or isinstance(degree, bool):
        raise InputError(f"{source}: expected an integer degree, got {degree!r}")
    return dict(degree=degree, knots=knots, ctrlpts=points, weights=weights, duration=stored)
