"""Optics benchmark: 512 x 512 pixels, 64 samples per ray.

``--field fem`` (default): the reference 8 N solution (quarter model, the coarse mesh of
bench/fea.py, solved first and not timed as optics), contact zone masked.
``--field boussinesq``: the Boussinesq point load (8 N, nu = 0.49) on the 3 mm sheet, the
singular core r < 1 mm masked. Prints the time to locate and sample the field along the
rays, to integrate the Jones path at the reference wavelength, to render the six
phase-stepped images, and to integrate and render the white-light image at 31
wavelengths; and the peak memory.

Sampling uses the symmetry of the model (mirror-image pixels share a ray) and an adaptive
lateral lattice of rays (``--lateral-step-mm``, 0 = every distinct pixel ray; see
optics.grid.sample_rays); ``--check`` also samples every pixel ray and prints the largest
difference of the fringe order. White light uses 31 wavelengths on the law's wavenumber
grid (optics.stressoptic.wavenumber_grid).

    python bench/optics.py [--json FILE] [--size 512] [--samples 64] [--field fem]
                           [--lateral-step-mm 0.4] [--check]
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import numpy as np

from fringekit.optics import (
    PSM4_ASSUMED,
    SIX_STEPS,
    Boussinesq,
    Camera,
    PixelGrid,
    integrate_samples,
    light_source,
    monochrome_image,
    sample_rays,
    white_light_image,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--field", choices=["fem", "boussinesq"], default="fem")
    ap.add_argument("--lateral-step-mm", type=float, default=0.4)
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args()
    law = PSM4_ASSUMED
    t_solve = 0.0
    if args.field == "fem":
        from fringekit.fea import Indenter, solve
        from fringekit.meshes import MeshSpec, Sizing, build_mesh
        from fringekit.optics import FEMStressField

        sizing = Sizing(h_contact=0.6e-3, refine_radius=2e-3, h_sheet=2e-3, h_far=8e-3)
        mesh = build_mesh(MeshSpec(sizing=sizing, symmetry="quarter"))
        ts = time.perf_counter()
        sols, _ = solve(mesh, [Indenter(normal_force=(8.0,))])
        t_solve = time.perf_counter() - ts
        field = FEMStressField(sols[-1])
    else:
        field = Boussinesq(F=8.0, nu=0.49, z_top=3e-3, thickness=3e-3, core=1e-3)
    grid = PixelGrid.from_field_of_view(20e-3, (args.size, args.size))
    t0 = time.perf_counter()
    step = args.lateral_step_mm * 1e-3 if args.lateral_step_mm > 0 else None
    samples = sample_rays(field, grid, args.samples, lateral_step=step)
    t1 = time.perf_counter()
    q, simple = integrate_samples(samples, law, law.wavelength_ref)
    q = q.reshape(args.size, args.size, 1, 4)
    t2 = time.perf_counter()
    cam = Camera(bit_depth=8)
    six = [monochrome_image(q[:, :, 0], a, cam) for a in SIX_STEPS]
    t3 = time.perf_counter()
    lam = law.wavenumber_grid(31)
    qw, _ = integrate_samples(samples, law, lam)
    rgb = white_light_image(qw.reshape(args.size, args.size, 31, 4), light_source("LED", lam), cam)
    t4 = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out = {
        "field": args.field,
        "time_fem_solve_s": round(t_solve, 3),
        "pixels": grid.n_pixels,
        "samples_per_ray": args.samples,
        "time_locate_s": round(t1 - t0, 3),
        "time_integrate_s": round(t2 - t1, 3),
        "time_six_step_s": round(t3 - t2, 3),
        "time_white_light_s": round(t4 - t3, 3),
        "peak_mem_mb": round(peak, 1),
        "max_fringe_order": float(np.nanmax(np.where(samples.valid, simple, np.nan))),
        "distinct_rays": int(samples.ds.shape[0]),
    }
    if args.check:
        from fringekit.optics import OpticalMap

        def order(smp):
            qq, sim = integrate_samples(smp, law, law.wavelength_ref)
            shape = grid.shape
            return OpticalMap(
                grid,
                np.array([law.wavelength_ref]),
                qq.reshape(*shape, 1, 4),
                np.where(smp.valid, sim, np.nan).reshape(shape),
                smp.valid.reshape(shape),
                True,
                law,
            ).fringe_order(0)

        tc = time.perf_counter()
        exact = sample_rays(field, grid, args.samples)
        out["time_locate_every_ray_s"] = round(time.perf_counter() - tc, 3)
        d = np.abs(order(samples) - order(exact))
        d = d[np.isfinite(d)]
        out["lattice_max_abs_dN"] = round(float(d.max()), 5)
        out["lattice_p99_abs_dN"] = round(float(np.percentile(d, 99)), 5)
    assert len(six) == 6 and rgb.shape == (args.size, args.size, 3)
    for k, v in out.items():
        print(f"{k:22s} {v}")
    print(f"{'total_s':22s} {t4 - t0:.2f}  (target: under 5 s)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(out, fh, indent=2)


if __name__ == "__main__":
    main()
