"""Frames of known loads, synthesised from a library: the test data of ``fringekit track``
(and a user's check of a tracking set-up before the camera is connected).

Each frame is the library's image of the contacts it lists (:mod:`fringekit.library.synth`,
the model ``invert`` and ``track`` fit), through the sensor's polariscope, with an exposure
gain and offset, Gaussian camera noise and 8-bit quantisation; colour frames are
sRGB-encoded for the CIE observer (the decoding ``invert`` applies).
"""

from __future__ import annotations

import os
from dataclasses import replace

import colour as cs
import numpy as np

from fringekit.config.files import load_config
from fringekit.config.inputs import optics_setup
from fringekit.inversion.model import ImageModel
from fringekit.inversion.read import pixel_grid
from fringekit.library.store import Library, LoadedIndenter
from fringekit.optics import write_image
from fringekit.output.folders import claim_output

__all__ = ["blank_model", "library_frames", "synthesise_frame"]


def synthesise_frame(
    model: ImageModel,
    contacts,
    *,
    camera="CIE1931",
    gain=0.8,
    offset=0.02,
    noise=0.0,
    rng=None,
    bit_depth: int = 8,
):
    """One frame (rows, cols) or (rows, cols, 3) uint8 (uint16 at ``bit_depth`` 16) of
    ``contacts`` (phase: the six steps, (rows, cols, 6)): rows of
    (x_mm, y_mm, Fz_N, Fx_N, Fy_N) on spheres of the library's first diameter; ``model``
    gives the library, grid, method and optics, ``camera`` the camera's sensitivities
    (CIE1931 frames are sRGB-encoded)."""
    d = model.lib.diameters_mm[0] * 1e-3
    inds = [LoadedIndenter(x * 1e-3, y * 1e-3, d, fx, fy, fz) for x, y, fz, fx, fy in contacts]
    lin, _ = model.linear(inds)
    img = gain * lin + offset
    if noise > 0:
        img = img + (rng or np.random.default_rng(0)).normal(0.0, noise, img.shape)
    img = np.clip(img, 0.0, 1.0)
    rows, cols = model.grid.shape
    if model.method == "rgb":
        img = img.reshape(rows, cols, 3)
        if camera == "CIE1931":
            img = np.clip(cs.cctf_encoding(img, function="sRGB"), 0.0, 1.0)
    elif model.method == "phase":
        img = img.reshape(rows, cols, -1)
    else:
        img = img[:, 0].reshape(rows, cols)
    top = 65535 if bit_depth == 16 else 255
    return np.round(img * top).astype(np.uint16 if bit_depth == 16 else np.uint8)


def library_frames(
    lib: Library,
    frames,
    folder: str | os.PathLike,
    *,
    pixels: int = 256,
    pixel_mm: float = 0.0625,
    method: str = "mono",
    noise: float = 0.0,
    seed: int = 0,
    bit_depth: int = 8,
    residual_ab=None,
) -> int:
    """Write one image per frame (``frame_0000.png``, ...; TIFF for 16-bit colour; six
    for phase, ``frame_0000_step1.png`` to ``step6``) into ``folder``; return how many
    frames (load states).

    Parameters
    ----------
    lib : Library
    frames : sequence of sequences of (x_mm, y_mm, Fz_N, Fx_N, Fy_N)
        The contacts of each frame (an empty one: no contact).
    folder : path
        A missing or empty folder, or one this function wrote before (replaced whole,
        so no frame of an earlier, longer stream is left behind); any other folder is
        refused (:class:`~fringekit.errors.InputError`) before a frame is written.
    pixels : int
        Frames of pixels x pixels, centred on the sensor origin.
    pixel_mm : float
        Pixel pitch on the sheet (mm).
    method : {"mono", "rgb", "phase"}
        A grey dark-field frame, a white-light colour one, or the six phase steps.
    noise : float
        Camera noise sd (of full scale) before 8-bit quantisation.
    seed : int
        Seed of the noise (the same frames on every run).
    bit_depth : {8, 16}
        Quantisation of the frames.
    residual_ab : (pixels * pixels, 2) array, optional
        A residual birefringence of the sheet (Pa m, summed slab pairs: the
        :class:`~fringekit.inversion.model.ImageModel`'s ``residual_ab``) in every frame.

    Returns
    -------
    int

    Examples
    --------
    See :func:`fringekit.tracking.track`.
    """
    cfg = load_config(lib.folder / "config.toml")
    model = replace(
        blank_model(lib, cfg, (pixels, pixels), pixel_mm, method), residual_ab=residual_ab
    )
    camera = optics_setup(cfg).camera.sensitivities
    if bit_depth not in (8, 16):
        raise ValueError(f"bit_depth {bit_depth} is not allowed; give 8 or 16")
    rng = np.random.default_rng(seed)
    with claim_output(folder, command="tracking.library_frames", option="folder") as out:
        for i, contacts in enumerate(frames):  # frames: each one image synthesis
            img = synthesise_frame(
                model, contacts, camera=camera, noise=noise, rng=rng, bit_depth=bit_depth
            )
            if method == "phase":
                for k in range(img.shape[2]):
                    write_image(out / f"frame_{i:04d}_step{k + 1}.png", img[..., k])
                continue
            suffix = "tif" if bit_depth == 16 and img.ndim == 3 else "png"
            write_image(out / f"frame_{i:04d}.{suffix}", img)
    return len(frames)


def blank_model(lib, cfg: dict, shape, pixel_mm: float, method: str, origin_px=None, optics=None):
    """The :class:`ImageModel` of frames of ``shape`` (rows, cols) at ``pixel_mm`` (mm)
    of the sensor ``cfg`` read by ``method``, without a measured image; ``optics``: the
    :class:`~fringekit.config.inputs.OpticsSetup` (default the config's)."""
    opt = optics_setup(cfg) if optics is None else optics
    grid = pixel_grid(shape, pixel_mm, origin_px)
    n = grid.n_pixels
    o = cfg["optics"]
    return ImageModel.build(
        lib,
        grid,
        method,
        np.zeros((n, 1)),
        np.ones(n, bool),
        opt,
        light=o["light"],
        white_light_wavelengths=o["white_light_wavelengths"],
    )
