"""``gms-fit RUN_DIR --out FILE``: a GMS friction model fitted to a friction_id run (``gms_fit``).

Paper 004 Fig. 4(b); the fit is ``core/friction/gms_fitting.fit_gms``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from servo_axis.cli.options import Subparsers, int_at_least, output_file, writing


def add_parser(commands: Subparsers) -> None:
    """The ``gms-fit`` command and its options."""
    gms = commands.add_parser(
        "gms-fit",
        help="fit a GMS friction model (Al-Bender et al. 2005; paper 004 Fig. 4(b)) to a "
        "friction_id run",
    )
    gms.add_argument(
        "run_dir", help="run directory of a friction_id run (e.g. friction_id_elastic)"
    )
    gms.add_argument("--out", required=True, type=output_file, help="GMS parameter file to write")
    gms.add_argument(
        "--elements",
        type=int_at_least(1, 20),
        default=4,
        help="number of Maxwell-slip elements, 1..20 (default 4)",
    )
    gms.add_argument(
        "--plot",
        type=output_file,
        help="PNG to write: measured and model torque against displacement",
    )
    gms.set_defaults(func=handle)


def handle(args: argparse.Namespace) -> int:
    """Fit, write the parameter file (and the figure), print the elements."""
    from servo_axis.analysis.units import DISPLACEMENT
    from servo_axis.gms_fit import fit_run_data, load_fit_data, plot_fit
    from servo_axis.storage import save_gms_parameters

    data = load_fit_data(Path(args.run_dir))
    fit = fit_run_data(data, elements=args.elements)
    p = fit.params
    with writing("--out", args.out):
        save_gms_parameters(
            Path(args.out),
            p,
            plant_model=data.plant_model,
            plant_fingerprint=data.plant_fingerprint,
        )
    print(f"GMS model with {p.elements} elements written to {args.out} ({data.plant_fingerprint})")
    print(f"  F_c = {p.coulomb_Nm:.6g} N m")
    um = DISPLACEMENT
    print(f"  {'element':>7}  {'k_i (N m/m)':>12}  {'alpha_i':>8}  {um.label('break-away'):>15}")
    for i, (k, a, b) in enumerate(zip(p.stiffness_Nm_per_m, p.weights, p.breakaway_m, strict=True)):
        print(f"  {i + 1:>7}  {k:>12.6g}  {a:>8.4f}  {um.format(b, '.4g'):>15}")
    print(f"  RMS residual = {fit.rms_residual_Nm:.4g} N m (samples from the first reversal on)")
    if args.plot:
        with writing("--plot", args.plot):
            plot_fit(fit, data.position_m, data.torque_Nm, Path(args.plot))
        print(f"figure written to {args.plot}")
    return 0
