"""The dispersion fit's values as a person reads them: each with its standard error, or
said to be held.

One rule for the live Waves panel and the one line ``holoview waves`` prints: a value is
written to the decimal place of its error's second significant digit, and a parameter
held at its given value has no error to write (``depth 1 mm (held)``, not ``1 ± 0``).
"""

from __future__ import annotations

import math

from holoview.processing.waves.dispersion import DispersionFit

__all__ = ["fit_values", "with_error"]


def with_error(value: float, error: float) -> str:
    """``value ± error`` with the error to two significant digits and the value to the same
    decimal place.

    Examples
    --------
    >>> with_error(76.76, 3.4), with_error(1234.5, 120.0)
    ('76.8 ± 3.4', '1234 ± 120')
    """
    if not (math.isfinite(error) and error > 0):
        return f"{value:.4g} ± {error:.2g}"
    decimals = max(0, 1 - math.floor(math.log10(error)))
    return f"{value:.{decimals}f} ± {error:.{decimals}f}"


def fit_values(fit: DispersionFit) -> tuple[str, str, str]:
    """Surface tension (mN/m), depth (mm) and flow (mm/s), each with its standard error or
    ``(held)``: ``('73.24 ± 0.51 mN/m', '1 mm (held)', '(20.1 ± 1.3, 8.6 ± 1.2) mm/s')``."""
    held = set(fit.held)

    def value(number: float, error: float, scale: float, unit: str, name: str) -> str:
        if name in held:
            return f"{number * scale:.4g} {unit} (held)"
        return f"{with_error(number * scale, error * scale)} {unit}"

    sigma = value(fit.surface_tension, fit.surface_tension_stderr, 1e3, "mN/m", "sigma")
    depth = value(fit.depth, fit.depth_stderr, 1e3, "mm", "depth")
    if "flow" in held:
        flow = f"({fit.flow[0] * 1e3:.3g}, {fit.flow[1] * 1e3:.3g}) mm/s (held)"
    else:
        ux, uy = (with_error(fit.flow[i] * 1e3, fit.flow_stderr[i] * 1e3) for i in (0, 1))
        flow = f"({ux}, {uy}) mm/s"
    return sigma, depth, flow
