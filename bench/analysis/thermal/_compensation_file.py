"""The thermal compensation file: TOML text to and from a :class:`CompensationModel`.

Layout (``format = "inertial-bench-thermal-compensation"``, ``version = 1``)::

    format = "inertial-bench-thermal-compensation"
    version = 1
    unit_serial = "QA-SIM-0005"
    unit_model = "QA-2000-SIM"
    created = "run 20261122-062505-a933"      # the caller's text (optional)
    temperature_source = "unit_sensor"        # unit_sensor | element
    reference_c = 25.0
    valid_range_c = [-40.0, 70.0]
    input_unit = "g"
    output_unit = "mA"
    notes = ""                                # optional
    element_lag_s = 412.5                     # optional, temperature_source = "element" only:
                                              # T_e = the unit's sensor through a first-order lag, s

    [quantities.k0]                           # one table per quantity, in model order
    role = "bias"                             # bias | scale_factor | k2 | cross_axis
    unit = "g"
    coefficients = [c0, c1, c2]               # q(T) = sum c_k (T - reference_c)^k
    covariance = [[...], [...], [...]]        # of the coefficients
    residual_rms = 1.2e-06                    # the fit's residuals, unit
    residual_max_abs = 2.0e-06
    prediction_std_max = 8.0e-07              # largest std of the curve over valid_range_c
    n_points = 7
    order_selection = "bic"                   # bic | loo | fixed
    # cross_input = "a_p"; sign = -1.0        # role cross_axis only

Numbers are written with Python's shortest round-trip repr, so a file reads back bit for
bit. Reading checks every key (unknown and missing keys too) and raises ValueError naming
the key, the value and what is allowed; the model's own checks
(:class:`~bench.analysis.thermal._compensation.CompensationModel`) then apply.
"""

from __future__ import annotations

import tomllib

from bench.analysis._checks import is_real
from bench.analysis.thermal._compensation import (
    FORMAT,
    SUPPORTED_VERSIONS,
    CompensationModel,
    QuantityCompensation,
)

_HEADER_KEYS = ("format", "version", "unit_serial", "unit_model", "created", "temperature_source",
                "reference_c", "valid_range_c", "input_unit", "output_unit", "notes", "element_lag_s",
                "quantities")
_QUANTITY_KEYS = ("role", "unit", "coefficients", "covariance", "residual_rms", "residual_max_abs",
                  "prediction_std_max", "n_points", "order_selection", "cross_input", "sign")
_ESCAPES = {"\\": "\\\\", '"': '\\"', "\n": "\\n", "\t": "\\t", "\r": "\\r"}


def _toml_value(v) -> str:
    if isinstance(v, str):  # a TOML basic string: backslash, quote and control characters escaped
        return '"' + "".join(_ESCAPES.get(ch, f"\\u{ord(ch):04x}" if ord(ch) < 0x20 or ord(ch) == 0x7F else ch)
                             for ch in v) + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v)
    return repr(float(v))  # shortest repr: reads back bit for bit


def compensation_to_toml(model: CompensationModel) -> str:
    """The compensation file's text (TOML).

    Layout in the module docstring; numbers are written with Python's shortest round-trip
    repr, so :func:`compensation_from_toml` reads the file back bit for bit.

    Parameters
    ----------
    model : CompensationModel
        The model to write.

    Returns
    -------
    str
        The file's text: three comment lines, the header keys, then one
        ``[quantities.<name>]`` table per quantity.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature, compensation_model
    >>> from bench.analysis.thermal import compensation_to_toml
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])  # noise-free points, for brevity
    >>> bias = QuantityPoints("k0", "bias", "g", t, 2e-3 + 5e-5 * (t - 25), np.full(t.size, 1e-5))
    >>> sf = QuantityPoints("k1", "scale_factor", "mA/g", t, 1.2 * (1 + 100e-6 * (t - 25)), np.full(t.size, 1e-5))
    >>> model = compensation_model(calibrate_over_temperature([bias, sf]), unit_serial="QA-0001",
    ...                            unit_model="QA-2000", input_unit="g", output_unit="mA")
    >>> text = compensation_to_toml(model)
    >>> text.splitlines()[3:5]
    ['format = "inertial-bench-thermal-compensation"', 'version = 1']
    >>> "[quantities.k1]" in text
    True
    """
    d = model.to_dict()
    lines = ["# inertial-bench thermal compensation model (docs/METHODS.md, \"Calibration over temperature\")",
             "# output = SF(T) * (x + B(T) + K2(T)*x^2 + sum_j sign_j * M_j(T) * u_j)",
             "# q(T) = sum_k coefficients[k] * (T - reference_c)^k, T in degC from temperature_source"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in d.items() if k != "quantities"]
    for name, q in d["quantities"].items():
        lines += ["", f"[quantities.{name}]"]
        lines += [f"{k} = {_toml_value(v)}" for k, v in q.items()]
    return "\n".join(lines) + "\n"


def _expect_keys(where: str, table, allowed: tuple[str, ...], required: tuple[str, ...]) -> None:
    if not isinstance(table, dict):
        raise ValueError(f"{where}: allowed a table, got {table!r}")
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise ValueError(f"{where + '.' if where else ''}{unknown[0]}: unknown key; allowed "
                         f"{', '.join(allowed)}")
    missing = [k for k in required if k not in table]
    if missing:
        raise ValueError(f"{where + '.' if where else ''}{missing[0]}: missing (required)")


def compensation_from_toml(text: str) -> CompensationModel:
    """Parse and validate a compensation file's text (ValueError naming the key and what is allowed).

    Every key is checked (unknown and missing keys too), then the model's own checks
    (:class:`CompensationModel`) apply.

    Parameters
    ----------
    text : str
        The file's TOML text (layout in the module docstring).

    Returns
    -------
    CompensationModel
        The validated model.

    Raises
    ------
    ValueError
        If the text is not valid TOML, a key is unknown or missing, ``format`` or
        ``version`` is not supported, or a value is not allowed; the message names the key
        (e.g. ``quantities.k0.coefficients``) and what is allowed.

    Examples
    --------
    >>> import numpy as np
    >>> from bench.analysis.thermal import QuantityPoints, calibrate_over_temperature, compensation_model
    >>> from bench.analysis.thermal import compensation_from_toml, compensation_to_toml
    >>> t = np.array([-40.0, -20.0, 0.0, 25.0, 45.0, 70.0])  # noise-free points, for brevity
    >>> bias = QuantityPoints("k0", "bias", "g", t, 2e-3 + 5e-5 * (t - 25), np.full(t.size, 1e-5))
    >>> sf = QuantityPoints("k1", "scale_factor", "mA/g", t, 1.2 * (1 + 100e-6 * (t - 25)), np.full(t.size, 1e-5))
    >>> model = compensation_model(calibrate_over_temperature([bias, sf]), unit_serial="QA-0001",
    ...                            unit_model="QA-2000", input_unit="g", output_unit="mA")
    >>> again = compensation_from_toml(compensation_to_toml(model))
    >>> again.to_dict() == model.to_dict()  # bit for bit
    True
    >>> compensation_from_toml(compensation_to_toml(model).replace("version = 1", "version = 9"))
    Traceback (most recent call last):
    ...
    ValueError: version = 9: this reader supports versions 1
    """
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"compensation file is not valid TOML: {exc}") from None
    _expect_keys("", doc, _HEADER_KEYS,
                 tuple(k for k in _HEADER_KEYS if k not in ("created", "notes", "element_lag_s")))
    if doc["format"] != FORMAT:
        raise ValueError(f"format = {doc['format']!r}: allowed {FORMAT!r}")
    version = doc["version"]
    if isinstance(version, bool) or version not in SUPPORTED_VERSIONS:
        raise ValueError(f"version = {version!r}: this reader supports versions "
                         f"{', '.join(map(str, SUPPORTED_VERSIONS))}")
    tables = doc["quantities"]
    if not isinstance(tables, dict) or not tables:
        raise ValueError(f"quantities = {tables!r}: allowed one or more [quantities.<name>] tables")
    quantities = []
    required = tuple(k for k in _QUANTITY_KEYS if k not in ("cross_input", "sign"))
    for name, t in tables.items():
        _expect_keys(f"quantities.{name}", t, _QUANTITY_KEYS, required)
        sign = t.get("sign", 1.0)
        if not is_real(sign):
            raise ValueError(f"quantities.{name}.sign = {sign!r}: allowed 1.0 or -1.0")
        quantities.append(QuantityCompensation(
            name=name, role=t["role"], unit=t["unit"], coefficients=t["coefficients"], covariance=t["covariance"],
            residual_rms=t["residual_rms"], residual_max_abs=t["residual_max_abs"],
            prediction_std_max=t["prediction_std_max"], n_points=t["n_points"],
            order_selection=t["order_selection"], cross_input=t.get("cross_input"), sign=float(sign)))
    return CompensationModel(
        unit_serial=doc["unit_serial"], unit_model=doc["unit_model"],
        temperature_source=doc["temperature_source"], reference_c=doc["reference_c"],
        valid_range_c=doc["valid_range_c"], input_unit=doc["input_unit"], output_unit=doc["output_unit"],
        quantities=tuple(quantities), created=doc.get("created", ""), notes=doc.get("notes", ""),
        version=version, element_lag_s=doc.get("element_lag_s"))
