"""A library calibrated to one physical sensor: the file ``fringekit sensor calibrate``
writes and ``invert --sensor`` / ``track --sensor`` read.

A library models an ideal sensor: its config's modulus and fringe value, a linear camera,
uniform light, a sheet free of stress at rest, the camera's pixel grid aligned with the
sheet. A :class:`CalibratedSensor` holds what one real device departs from that by, and
applies it:

- **the sheet**: a modulus scale ``k`` (the library read at F / k, its stresses times k:
  :meth:`~fringekit.library.store.Library.scaled`) and a fringe-value scale ``s`` (the
  material fringe value f_sigma times s);
- **the camera**: its black level b (per channel, raw units) and response, a power law:
  linear intensity = ((v - b) / (1 - b)) ** gamma of the stored value v in [0, 1];
- **the light and the sheet at rest**: the relative illumination L(x) (mean 1) and the
  rest frame's intensity R(x) (linear, black removed): a frame is read as
  (linear - R) / L, the standard flat-field and reference-frame correction. It is exact
  for light that adds to the fringes' (glare, ghosts, stray light). For the dark-field
  methods (grey and colour) a residual birefringence's light is not additive: it
  scales the load's light by cos d_r and leaves a cross term up to (sin d_r) / 2 of
  the full-scale light (d_r the residual retardation;
  :mod:`fringekit.inversion.rest` gives the formula), so the subtraction holds only
  where the residual is small. With six rest steps (the phase method's rest, or a grey
  sensor's ``--residual-steps``) the residual retarder itself is calibrated
  (``residual``: the summed slab pair of a stress frozen evenly through the sheet, at the
  sensor's fringe value) and put into the model in series with the loads' retardation,
  as ``invert``'s rest steps are (:meth:`~fringekit.inversion.rest.RestFrames.retarder`);
  no rest light is subtracted;
- **the geometry**: the pixel pitch on the sheet, the pixel of the sheet's origin and the
  rotation of the sheet's axes in the image (positive: the sheet's x axis turned
  counter-clockwise from the image's rows). The image is fitted in its own axes and the
  positions and tangential loads are turned into the sheet's.

The file is JSON: the sensor config, the library's identity (its manifest checksum), the
image size and method, the scales, the camera, the geometry, the maps on a coarse grid
(at most :data:`MAP_CELLS` cells a side, interpolated bilinearly to the image) and every
fitted value's 1-sigma.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from skimage.transform import resize

from fringekit.errors import ConfigError
from fringekit.output.folders import atomic_write

__all__ = [
    "FORMAT",
    "MAP_CELLS",
    "CalibratedSensor",
    "as_calibrated",
    "coarse_map",
    "fine_map",
    "is_sensor_file",
    "linearise",
    "load_sensor",
]

#: The file's format; another one is refused.
FORMAT = "fringekit-sensor/1"
#: The maps are stored on a grid of at most this many cells a side.
MAP_CELLS = 64


def linearise(raw: np.ndarray, black, gamma: float) -> np.ndarray:
    """Linear intensities of stored values (..., C): ((v - b) / (1 - b)) ** gamma, 0 below
    the black level.

    Examples
    --------
    >>> float(linearise(np.array([[0.5]]), [0.0], 2.0)[0, 0])
    0.25
    """
    b = np.asarray(black, float)
    return np.clip((np.asarray(raw, float) - b) / (1.0 - b), 0.0, None) ** gamma


def coarse_map(image: np.ndarray, cells: int = MAP_CELLS) -> np.ndarray:
    """A map (rows, cols[, C]) averaged down to at most ``cells`` cells a side (anti-aliased
    resampling, :func:`skimage.transform.resize`).

    Examples
    --------
    >>> coarse_map(np.ones((256, 128))).shape
    (64, 32)
    """
    a = np.asarray(image, float)
    f = max(a.shape[0], a.shape[1]) / cells
    if f <= 1:
        return a.copy()
    shape = (max(1, round(a.shape[0] / f)), max(1, round(a.shape[1] / f)), *a.shape[2:])
    return resize(a, shape, order=1, anti_aliasing=True, mode="edge")


def fine_map(m: np.ndarray, shape) -> np.ndarray:
    """A coarse map interpolated bilinearly to ``shape`` (rows, cols)."""
    return resize(np.asarray(m, float), (*shape, *m.shape[2:]), order=1, mode="edge")


@dataclass(frozen=True)
class CalibratedSensor:
    """One physical sensor's departures from its library's model (module docstring).

    Attributes
    ----------
    config : dict
        The sensor's effective config (sheet, optics, camera), as the library's.
    library_sha256 : str
        The ``manifest_sha256`` of the library it was calibrated with.
    method : {"rgb", "mono", "phase"}
    shape : (rows, cols)
        The image size (px).
    pixel_mm : float
        The pixel pitch on the sheet (mm).
    origin_px : (row, col)
        The image pixel of the sheet's origin.
    rotation_deg : float
        The sheet's x axis in the image, counter-clockwise from the image's x (deg).
    modulus_scale, fringe_scale : float
        The sheet's modulus and material fringe value over the library's.
    gamma : float
        The camera response's exponent (1: linear).
    black : (C,) tuple
        The black level per channel (raw units, 0-1; one for the six phase steps).
    illumination : (h, w) array or None
        Relative illumination, mean 1, on a coarse grid.
    rest : (h, w, C) array or None
        The rest frame's linear intensity, black removed, on a coarse grid.
    sd : dict
        1-sigma of the fitted values, by attribute name.
    report : dict
        How the calibration went (frames, residuals, warnings).
    residual : (h, w, 2) array or None
        The residual retarder of the sheet at rest (six rest steps) on a coarse grid: the
        summed slab pair ((sigma_xx - sigma_yy) dz, 2 sigma_xy dz) through the thickness
        (Pa m) at this sheet's fringe value (:meth:`residual_ab`).

    Examples
    --------
    An uncalibrated sensor changes nothing; a file is read back as it was written:

    >>> import tempfile, numpy as np
    >>> s = CalibratedSensor({}, "abc", "mono", (4, 6), 0.1, (1.5, 2.5), 0.0, 1.0, 1.0,
    ...                      1.0, (0.0,), None, None)
    >>> raw = np.full((4, 6, 1), 0.25)
    >>> bool(np.allclose(s.linear(raw), raw))
    True
    >>> path = s.save(tempfile.mkdtemp() + "/sensor.json")
    >>> load_sensor(path).shape
    (4, 6)
    """

    config: dict
    library_sha256: str
    method: str
    shape: tuple
    pixel_mm: float
    origin_px: tuple
    rotation_deg: float
    modulus_scale: float
    fringe_scale: float
    gamma: float
    black: tuple
    illumination: np.ndarray | None = field(default=None, repr=False)
    rest: np.ndarray | None = field(default=None, repr=False)
    sd: dict = field(default_factory=dict)
    report: dict = field(default_factory=dict, repr=False)
    residual: np.ndarray | None = field(default=None, repr=False)

    def check(self, lib, shape=None, method: str | None = None, where: str = "--sensor") -> None:
        """Refuse, in one line, a library, image size or method this sensor was not
        calibrated for (:class:`~fringekit.errors.ConfigError`); a size or method not
        given is not checked."""
        sha = lib.manifest.get("manifest_sha256")
        if sha != self.library_sha256:
            raise ConfigError(
                f"{where}: calibrated with another library (manifest_sha256 "
                f"{self.library_sha256[:12]}..., this one {str(sha)[:12]}...); calibrate "
                "the sensor with this library (fringekit sensor calibrate)"
            )
        if shape is not None and tuple(shape) != tuple(self.shape):
            raise ConfigError(
                f"{where}: calibrated for {self.shape[0]} x {self.shape[1]} px images; this "
                f"one is {shape[0]} x {shape[1]} px"
            )
        if method is not None and method != self.method:
            raise ConfigError(
                f"{where}: calibrated for --method {self.method}; got --method {method}"
            )

    @property
    def calibrated(self) -> bool:
        """False for a sensor file of ``fringekit sensor init`` (a config, an image size and
        a pitch, nothing fitted): frames are then read as without one."""
        return bool(self.report.get("calibrated", True))

    @classmethod
    def uncalibrated(cls, cfg: dict, lib, shape, method: str, pixel_mm: float, origin_px=None):
        """The sensor file of a sensor config with nothing fitted (``fringekit sensor
        init``): the config, the library's identity, the image size, method, pitch and
        origin (default the image centre); the scales 1, a linear camera, no maps.

        Examples
        --------
        >>> class Lib:
        ...     manifest = {"manifest_sha256": "ab"}
        >>> s = CalibratedSensor.uncalibrated({}, Lib(), (4, 6), "rgb", 0.1)
        >>> s.origin_px, s.black, s.calibrated
        ((1.5, 2.5), (0.0, 0.0, 0.0), False)
        """
        rows, cols = (int(v) for v in shape)
        origin = tuple(origin_px) if origin_px is not None else ((rows - 1) / 2, (cols - 1) / 2)
        black = (0.0,) * (3 if method == "rgb" else 1)  # the six phase steps: one camera
        sha = lib.manifest.get("manifest_sha256", "")
        return cls(
            cfg,
            sha,
            method,
            (rows, cols),
            pixel_mm,
            origin,
            0.0,
            1.0,
            1.0,
            1.0,
            black,
            report={"calibrated": False},
        )

    def grid_options(self, pixel_mm=None, origin_px=None) -> tuple[float, tuple]:
        """The pitch (mm) and origin pixel of the calibration; an option that says
        otherwise is refused (one :class:`~fringekit.errors.ConfigError` line)."""
        if pixel_mm is not None and abs(pixel_mm / self.pixel_mm - 1) > 1e-6:
            raise ConfigError(
                f"--pixel-mm {pixel_mm:g}: the calibrated sensor gives the pitch "
                f"({self.pixel_mm:.6g} mm); leave --pixel-mm out"
            )
        if origin_px is not None and math.dist(origin_px, self.origin_px) > 1e-6:
            raise ConfigError(
                f"--origin-px {origin_px[0]:g} {origin_px[1]:g}: the calibrated sensor gives "
                f"the origin ({self.origin_px[0]:.2f}, {self.origin_px[1]:.2f}); leave "
                "--origin-px out"
            )
        return self.pixel_mm, tuple(self.origin_px)

    def summary(self, source=None) -> dict:
        """What a run's ``summary.json`` says of the calibrated sensor it used."""
        keys = ("modulus_scale", "fringe_scale", "gamma", "rotation_deg", "pixel_mm")
        return {
            "file": source,
            **{k: getattr(self, k) for k in keys},
            "origin_px": list(self.origin_px),
        }

    def model_inputs(self, lib, optics, shape, method: str):
        """The library and optics that frames of ``shape`` read by ``method`` are fitted
        with: this sheet's (:meth:`library`, :meth:`optics`), once :meth:`check` has
        passed."""
        self.check(lib, shape, method)
        return self.library(lib), self.optics(optics)

    def library(self, lib):
        """The library as this sheet's (modulus scale applied)."""
        return lib.scaled(self.modulus_scale)

    def optics(self, optics):
        """An :class:`~fringekit.config.inputs.OpticsSetup` with this sheet's fringe value."""
        law = replace(optics.law, f_sigma=optics.law.f_sigma * self.fringe_scale)
        return replace(optics, law=law)

    def linear(self, raw: np.ndarray) -> np.ndarray:
        """Linear intensities (rows, cols, C) of stored values ``raw`` (rows, cols, C) in
        [0, 1]: the black level removed, the response undone."""
        return linearise(raw, self.black, self.gamma)

    def encode(self, linear: np.ndarray) -> np.ndarray:
        """Stored values (rows, cols, C) in [0, 1] of a frame whose linear intensities, as
        the library's ideal sensor sees them, are ``linear`` (rows, cols, C): times the
        illumination, plus the rest frame, through the response and black level (the
        inverse of :meth:`linear` then :meth:`correct`)."""
        out = np.asarray(linear, float)
        if self.illumination is not None:
            out = out * fine_map(self.illumination, out.shape[:2])[..., None]
        if self.rest is not None:
            out = out + fine_map(self.rest, out.shape[:2]).reshape(out.shape[:2] + (-1,))
        b = np.asarray(self.black, float)
        return np.clip(b + (1.0 - b) * np.clip(out, 0.0, None) ** (1.0 / self.gamma), 0.0, 1.0)

    def correct(self, linear: np.ndarray) -> np.ndarray:
        """A frame's linear intensities (rows, cols, C) as the library's ideal sensor
        would see them: the rest frame removed, divided by the illumination."""
        out = np.asarray(linear, float)
        if self.rest is not None:
            out = out - fine_map(self.rest, out.shape[:2]).reshape(out.shape[:2] + (-1,))
        if self.illumination is not None:
            out = out / np.clip(fine_map(self.illumination, out.shape[:2]), 1e-3, None)[..., None]
        return out

    def residual_ab(self, shape) -> np.ndarray | None:
        """The residual retarder (P, 2) (Pa m, P = rows * cols) on an image of ``shape``
        (the model's ``residual_ab``), or None without one."""
        if self.residual is None:
            return None
        return fine_map(self.residual, shape).reshape(-1, 2)

    def to_sheet(self, values: np.ndarray, sd: bool = False) -> np.ndarray:
        """Indenter parameters (n, 5) x, y (mm), Fz, Fx, Fy (N) fitted in the image's axes,
        in the sheet's: positions and tangential loads turned by ``-rotation_deg``;
        ``sd``: the values are 1-sigma, turned as independent errors (sqrt(c^2 sx^2 +
        s^2 sy^2), ...)."""
        q = np.array(values, float).reshape(-1, 5)
        t = math.radians(self.rotation_deg)
        c, s = math.cos(t), math.sin(t)
        for i, j in ((0, 1), (3, 4)):
            x, y = q[:, i].copy(), q[:, j].copy()
            if sd:
                q[:, i], q[:, j] = np.hypot(c * x, s * y), np.hypot(s * x, c * y)
            else:
                q[:, i], q[:, j] = c * x + s * y, -s * x + c * y
        return q

    def save(self, path) -> Path:
        """Write the JSON file; return its path."""
        path = Path(path)
        d = {
            "format": FORMAT,
            **{k: getattr(self, k) for k in _SCALARS},
            "shape": list(self.shape),
            "origin_px": list(self.origin_px),
            "black": list(self.black),
            "illumination": None if self.illumination is None else self.illumination.tolist(),
            "rest": None if self.rest is None else self.rest.tolist(),
            "residual": None if self.residual is None else self.residual.tolist(),
            "sd": self.sd,
            "report": self.report,
            "config": self.config,
        }
        return atomic_write(path, json.dumps(d, indent=1, default=_plain))


_SCALARS = (
    "library_sha256",
    "method",
    "pixel_mm",
    "rotation_deg",
    "modulus_scale",
    "fringe_scale",
    "gamma",
)


def _plain(v):
    """JSON for numpy scalars and arrays."""
    return v.tolist() if hasattr(v, "tolist") else str(v)


def as_calibrated(sensor) -> CalibratedSensor | None:
    """The sensor ``--sensor`` names: one already read, or a sensor file (read); None for
    None. Anything else (a config file, a folder) is refused in one line: ``--sensor``
    takes sensor files only (``fringekit sensor calibrate``, or ``sensor init`` for a
    config with nothing fitted).

    Examples
    --------
    >>> as_calibrated(None) is None
    True
    >>> try:
    ...     as_calibrated("sensor.toml")
    ... except ValueError as exc:
    ...     print(str(exc)[:60])
    --sensor sensor.toml: give a sensor file (.json), made by fr
    """
    if sensor is None or isinstance(sensor, CalibratedSensor):
        return sensor
    if Path(sensor).suffix.lower() != ".json":
        raise ConfigError(
            f"--sensor {sensor}: give a sensor file (.json), made by fringekit sensor "
            "calibrate, or by fringekit sensor init from a sensor config"
        )
    return load_sensor(sensor)


def is_sensor_file(path) -> bool:
    """Whether ``path`` is a sensor file fringekit wrote (its JSON names :data:`FORMAT`'s
    kind), which a new calibration may replace.

    Examples
    --------
    >>> is_sensor_file("no/such/file.json")
    False
    """
    try:
        d = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(d, dict) and str(d.get("format", "")).startswith("fringekit-sensor/")


def load_sensor(path) -> CalibratedSensor:
    """Read a sensor file (``fringekit sensor calibrate``); any defect is one
    :class:`~fringekit.errors.ConfigError` line naming the file."""
    path = Path(path)
    try:
        d = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"--sensor {path}: not a readable sensor file ({exc})") from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        got = d.get("format") if isinstance(d, dict) else None
        raise ConfigError(
            f"--sensor {path}: format {got!r} is not {FORMAT!r} (write one with "
            "fringekit sensor calibrate)"
        )
    try:
        maps = {k: d[k] for k in ("illumination", "rest")}
        maps["residual"] = d.get("residual")  # none in a file of before phase was calibrated
        maps = {k: None if v is None else np.asarray(v, float) for k, v in maps.items()}
        return CalibratedSensor(
            config=d["config"],
            shape=tuple(int(v) for v in d["shape"]),
            origin_px=tuple(float(v) for v in d["origin_px"]),
            black=tuple(float(v) for v in d["black"]),
            sd=d.get("sd", {}),
            report=d.get("report", {}),
            **{k: d[k] for k in _SCALARS},
            **maps,
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(
            f"--sensor {path}: a corrupt sensor file ({exc!r} missing or bad)"
        ) from None
