"""Polariscopes: plane and circular, dark/bright field, the six phase steps, element errors.

Element angles are measured from the x axis (rad); an element at angle a has the Jones
matrix R(-a) M R(a) with R(a) = [[cos a, sin a], [-sin a, cos a]] (optics.jones). A
polariser at angle a passes the field component along (cos a, sin a).

Six-step phase shifting (the table of ``docs/theory.md``; Ramesh, Digital Photoelasticity,
2000): polariser at pi/2, quarter-wave plates xi (before the model) and eta (after),
analyser beta. With these sign conventions the intensities follow the table's column
``I / (I_a/2)`` exactly; :func:`six_step_intensities` is checked against it by test.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .jones import to_matrix

__all__ = [
    "Arrangement",
    "SIX_STEPS",
    "dark_field_circular",
    "bright_field_circular",
    "plane_polariscope",
    "intensity",
    "intensity_form",
    "six_step_arrangements",
]


def _rot(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, s], [-s, c]])


def _polariser(a: float) -> np.ndarray:
    return _rot(-a) @ np.diag([1.0, 0.0]) @ _rot(a)


def _waveplate(a: float, retardance: float) -> np.ndarray:
    d = np.diag([np.exp(-0.5j * retardance), np.exp(0.5j * retardance)])
    return _rot(-a) @ d @ _rot(a)


@dataclass(frozen=True)
class Arrangement:
    """One polariscope setting: polariser, quarter-wave plates and analyser.

    Parameters
    ----------
    polariser : float
        Polariser angle (rad, from the x axis).
    analyser : float
        Analyser angle (rad).
    qwp_in, qwp_out : float or None
        Fast-axis angles of the quarter-wave plates before and after the model (rad);
        None for a plane polariscope.
    qwp_error : float
        Retardance error of both quarter-wave plates (rad): each has pi/2 + qwp_error.
    name : str
        Label used in file names.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import SIX_STEPS, intensity, retarder
    >>> step2 = SIX_STEPS[1]  # dark-field circular
    >>> step2.name, step2.input_state().shape, step2.output_matrix().shape
    ('step2', (2,), (2, 2))
    >>> off = step2.misaligned(analyser=np.radians(1.0))  # a 1 degree analyser error
    >>> round(float(intensity(retarder(0.0, 0.0), off)), 6)  # leaks sin^2(1 deg) at zero load
    0.000305
    """

    polariser: float
    analyser: float
    qwp_in: float | None = None
    qwp_out: float | None = None
    qwp_error: float = 0.0
    name: str = ""

    def misaligned(self, *, polariser=0.0, qwp_in=0.0, qwp_out=0.0, analyser=0.0, qwp_error=0.0):
        """Same arrangement with angle errors (rad) added and a quarter-wave error set."""
        return replace(
            self,
            polariser=self.polariser + polariser,
            analyser=self.analyser + analyser,
            qwp_in=None if self.qwp_in is None else self.qwp_in + qwp_in,
            qwp_out=None if self.qwp_out is None else self.qwp_out + qwp_out,
            qwp_error=self.qwp_error + qwp_error,
        )

    def input_state(self) -> np.ndarray:
        """Jones vector (2,) entering the model."""
        e = np.array([np.cos(self.polariser), np.sin(self.polariser)], dtype=complex)
        if self.qwp_in is not None:
            e = _waveplate(self.qwp_in, np.pi / 2 + self.qwp_error) @ e
        return e

    def output_matrix(self) -> np.ndarray:
        """Jones matrix (2, 2) from the model to the detector."""
        m = _polariser(self.analyser).astype(complex)
        if self.qwp_out is not None:
            m = m @ _waveplate(self.qwp_out, np.pi / 2 + self.qwp_error)
        return m


def dark_field_circular(**err) -> Arrangement:
    """Circular polariscope, dark field (step 2 of the six-step table).

    I = I_a/2 (1 - cos d) for a retarder d: black at zero load.

    Parameters
    ----------
    **err : float
        Element errors (rad) as in :meth:`Arrangement.misaligned`: ``polariser``,
        ``qwp_in``, ``qwp_out``, ``analyser``, ``qwp_error``.

    Returns
    -------
    Arrangement

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import dark_field_circular, intensity, retarder
    >>> [round(float(intensity(retarder(d, 0.3), dark_field_circular())), 6) for d in (0, np.pi)]
    [0.0, 1.0]
    """
    return SIX_STEPS[1].misaligned(**err) if err else SIX_STEPS[1]


def bright_field_circular(**err) -> Arrangement:
    """Circular polariscope, bright field (step 1 of the six-step table).

    I = I_a/2 (1 + cos d) for a retarder d: bright at zero load.

    Parameters
    ----------
    **err : float
        Element errors (rad) as in :meth:`Arrangement.misaligned`.

    Returns
    -------
    Arrangement

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import bright_field_circular, intensity, retarder
    >>> [round(float(intensity(retarder(d, 0.3), bright_field_circular())), 6) for d in (0, np.pi)]
    [1.0, 0.0]
    """
    return SIX_STEPS[0].misaligned(**err) if err else SIX_STEPS[0]


def plane_polariscope(polariser: float = 0.0, *, dark: bool = True) -> Arrangement:
    """Plane polariscope: dark field with crossed analyser, bright with parallel.

    Parameters
    ----------
    polariser : float
        Polariser angle (rad).
    dark : bool
        Crossed (dark field) or parallel analyser.

    Returns
    -------
    Arrangement
        Without quarter-wave plates: the intensity depends on the isoclinic.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import intensity, plane_polariscope, retarder
    >>> crossed = plane_polariscope(0.0)
    >>> round(float(intensity(retarder(np.pi, 0.0), crossed)), 6)  # axes along the polariser
    0.0
    >>> round(float(intensity(retarder(np.pi, np.pi / 4), crossed)), 6)  # at 45 degrees
    1.0
    """
    analyser = polariser + (np.pi / 2 if dark else 0.0)
    return Arrangement(polariser, analyser, name="plane_dark" if dark else "plane_bright")


_P4 = np.pi / 4
#: The six phase-stepped arrangements of ``docs/theory.md`` (polariser at pi/2).
SIX_STEPS = (
    Arrangement(np.pi / 2, np.pi / 2, 3 * _P4, _P4, name="step1"),
    Arrangement(np.pi / 2, 0.0, 3 * _P4, _P4, name="step2"),
    Arrangement(np.pi / 2, 0.0, 3 * _P4, 0.0, name="step3"),
    Arrangement(np.pi / 2, _P4, 3 * _P4, _P4, name="step4"),
    Arrangement(np.pi / 2, 0.0, _P4, 0.0, name="step5"),
    Arrangement(np.pi / 2, _P4, _P4, 3 * _P4, name="step6"),
)


def six_step_arrangements(**err) -> tuple[Arrangement, ...]:
    """The six phase-stepped arrangements, each with the same element errors.

    Parameters
    ----------
    **err : float
        Element errors (rad) as in :meth:`Arrangement.misaligned`.

    Returns
    -------
    tuple of 6 Arrangement
        :data:`SIX_STEPS` (in :data:`analysis.SIX_STEP_ORDER`) when no error is given.

    Examples
    --------
    Intensities of a retarder of d = pi/2 at 22.5 degrees; steps 1 and 2 (1 +- cos d)
    are equal there:

    >>> import numpy as np
    >>> from fringekit.optics import intensity, retarder, six_step_arrangements
    >>> q = retarder(np.pi / 2, np.pi / 8)
    >>> [round(float(intensity(q, a)), 3) for a in six_step_arrangements()]
    [0.5, 0.5, 0.146, 0.854, 0.854, 0.146]
    """
    return tuple(a.misaligned(**err) for a in SIX_STEPS) if err else SIX_STEPS


def intensity(q: np.ndarray, arrangement: Arrangement, source: float = 1.0) -> np.ndarray:
    """Detected intensity for model quaternions q (..., 4) in one arrangement.

    Reflection is included by passing U_refl's quaternion (optics.jones.qtranspose).

    Parameters
    ----------
    q : (..., 4) float array
        Path quaternions of the model (:mod:`optics.jones`).
    arrangement : Arrangement
    source : float
        I_a, the intensity after the polariser for a perfect element, so a
        dark-field circular polariscope gives I = I_a/2 (1 - cos d) for a retarder d.

    Returns
    -------
    (...) float array
        Intensity, in units of ``source``.

    Examples
    --------
    >>> import numpy as np
    >>> from fringekit.optics import dark_field_circular, intensity, retarder
    >>> d = np.linspace(0, 2 * np.pi, 5)  # rad
    >>> intensity(retarder(d, 0.0), dark_field_circular()).round(3).tolist()
    [0.0, 0.5, 1.0, 0.5, 0.0]
    """
    q = np.asarray(q, float)
    m = intensity_form(arrangement)
    # q^T M q as sum over i <= j of (2 - d_ij) M_ij q_i q_j, skipping the terms a
    # perfect arrangement zeroes (a dark field keeps 2 of 10): 5-18x faster than a
    # (N, 4) @ (4, 4) product on a million quaternions, whose inner size is too small
    # for BLAS
    comps = np.moveaxis(q, -1, 0)
    out = np.zeros(q.shape[:-1])
    tiny = 1e-14 * float(np.abs(m).max())
    for i in range(4):  # the 10 terms of a 4 x 4 quadratic form
        for j in range(i, 4):
            c = m[i, j] * (1.0 if i == j else 2.0)
            if abs(c) > tiny:
                out += (source * c) * comps[i] * comps[j]
    return out


def intensity_form(arrangement: Arrangement) -> np.ndarray:
    """(4, 4) real symmetric M with I = q^T M q for model quaternions q (I_a = 1).

    The output field A U e_in is linear in q (U = w I - i (x s1 + y s2 + z s3)), so the
    intensity |A U e_in|^2 is a quadratic form in q; M is read off the Jones calculus
    on the basis quaternions (polarisation identity). One 4 x 4 product per pixel then
    replaces complex 2 x 2 matrix products (tests compare both).
    """
    e_in = arrangement.input_state()
    out = arrangement.output_matrix()
    basis = np.eye(4)
    cols = np.einsum("ij,bjk,k->bi", out, to_matrix(basis), e_in)  # (4, 2): A U(e_b) e_in
    return np.real(cols.conj() @ cols.T)
