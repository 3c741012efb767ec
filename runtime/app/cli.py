"""The `dtdyn` command: generate, show, simulate."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path


def _generate(args) -> int:
    from dtdyn.derive import emit  # SymPy and jinja2: build time only

    dest = Path(args.out) if args.out else emit.GENERATED
    if args.check:
        bad = emit.check(dest)
        if bad:
            print(f"generated/ is out of date in {dest}: {', '.join(bad)}\n"
                  "run `dtdyn generate` to rewrite it", file=sys.stderr)
            return 1
        print(f"generated/ is up to date ({dest})")
        return 0
    files = emit.write(dest)
    print(f"wrote {len(files)} files to {dest}")
    return 0


def _show(args) -> int:
    import sympy as sp

    from dtdyn.derive import dttmm, integrators

    if args.scheme not in integrators.SCHEMES:
        print(f"unknown scheme {args.scheme!r}; available: {', '.join(integrators.SCHEMES)}",
              file=sys.stderr)
        return 2
    der = integrators.derive_scheme(args.scheme)
    s = der.scheme
    print(f"{s.title} ({s.name}); {s.reference}\n{s.notes}\n\nDefining relations:")
    for rel in s.relations:
        print("   ", sp.sstr(rel.subs(s.substitutions)))
    print(f"\nEquilibrium: M ae + C ve + K xe = ({sp.sstr(der.w0)}) F_n + ({sp.sstr(der.w1)}) F_n+1")
    rows = [] if der.explicit else [("A", der.A), ("B", der.B), ("D", der.D), ("E", der.E)]
    rows += [("Dx", der.Dx), ("Ex", der.Ex), ("Dv", der.Dv), ("Ev", der.Ev)]
    print("Displacement form: ae = A xe + B, ve = D xe + E" if not der.explicit
          else "Explicit: no displacement form")
    print("Acceleration form: xe = Dx ae + Ex, ve = Dv ae + Ev\n")
    for name, expr in rows:
        print(f"  {name:3s}= {sp.sstr(expr)}")
    for form in dttmm.FORMS:
        if form == "displacement" and der.explicit:
            continue
        maps = dttmm.form_maps(form, der)
        subs = {dttmm.p: maps["p"], dttmm.r: maps["r"], dttmm.alpha: maps["alpha_u"],
                dttmm.b_n: maps["b"]}
        T = dttmm.station_step().subs(subs)
        unknown = "u = xe - x0, the increment" if form == "displacement" else "u = ae"
        print(f"\nDT-TMM station matrix, {form} form ({unknown}), "
              "[u_n-1, f_n, 1] -> [u_n, f_n+1, 1]:")
        sp.pprint(T, use_unicode=False)
        print(f"  kappa = {sp.sstr(sp.simplify(dttmm.KAPPA.subs(subs)))}, "
              "Delta = k (q_n - q_n-1) + c (s_n - s_n-1) with, at each mass,\n"
              f"  q = {sp.sstr(maps['q'])}, s = {sp.sstr(maps['s'])}, b = {sp.sstr(maps['b'])}")
    return 0


def _simulate_nonlinear(args, sc) -> int:
    """`dtdyn simulate` of a scene with [[element]]: run, store, print times and Newton stats."""
    from dtdyn.app import scene as scenes
    from dtdyn.nonlinear.response import DtdynStepStabilityError, NewtonError

    params = "".join(f", {k} = {v:g}" for k, v in sc.scheme_params.items())
    substeps = sc.nonlinear.get("substeps", 1)
    print(f"{sc.title}: {sc.n_dof} DOF, {sc.n_steps} steps of dt = {sc.dt:g} s, "
          f"{len(sc.elements)} nonlinear element(s), scheme {sc.scheme}{params} "
          f"({substeps} substep(s) per sample, backend {sc.backend})")
    for k, el in enumerate(sc.elements):
        print(f"  element[{k}]: {el.describe()}")
    try:
        response, report = scenes.run_scene(sc)
    except (NewtonError, DtdynStepStabilityError) as exc:  # the run failed: nothing is written
        print(f"dtdyn simulate: error: {exc}", file=sys.stderr)
        return 1
    if args.out:
        scenes.save_results(args.out, response, sc)
    if args.plot:
        scenes.plot_response(args.plot, response, sc)
    n_steps = sc.n_steps * report["substeps"] + 1  # as nonlinear_response counts them
    print(f"construct time: {report['construct_time_s'] * 1e3:.2f} ms, compile or cache load: "
          f"{report['compile_time_s'] * 1e3:.2f} ms, setup: {report['setup_time_s'] * 1e3:.2f} ms")
    print(f"run time: {report['run_time_s'] * 1e3:.2f} ms ({report['backend']} backend, "
          f"{report['run_time_s'] / n_steps * 1e6:.3f} us per step of h = dt / "
          f"{report['substeps']})")
    iters = report["newton_iterations"]
    its = ("not counted (casadi backend)" if iters is None
           else f"max {iters['max']}, mean {iters['mean']:.3f}")
    print(f"Newton iterations per step: {its}; max residual: {report['max_residual']:.3e}")
    for what, path in (("results", args.out), ("plot", args.plot)):
        if path:
            print(f"{what}: {path}")
    return 0


def _simulate(args) -> int:
    from dtdyn.app import scene as scenes

    sc = scenes.load_scene(args.scene)
    if not sc.linear:
        return _simulate_nonlinear(args, sc)
    if sc.kind == "matrices":
        how = (f"assembled {'sparse' if sc.sparse else 'dense'} M, C, K, {sc.form} form, "
               f"backend {sc.backend}")
    else:
        how = f"{sc.form} form, {sc.sweep} sweep, backend {sc.backend}"
    print(f"{sc.title}: {sc.n_dof} DOF, {sc.n_steps} steps of dt = {sc.dt:g} s, scheme "
          f"{sc.scheme} ({how})")
    if sc.backend == "c":
        import time

        from dtdyn._engine import kernels

        t0 = time.perf_counter()
        kernels.c_chain_function(sc.scheme)
        print(f"C kernel compile or cache load: {time.perf_counter() - t0:.3f} s")
    long_run = sc.n_steps * sc.n_dof > 5e7
    response, report = scenes.run_scene(sc, progress=long_run and not args.quiet)
    if args.out:
        scenes.save_results(args.out, response, sc)
    if args.plot:
        scenes.plot_response(args.plot, response, sc)
    print(f"run time: {report['run_time_s'] * 1e3:.2f} ms ({response.info['backend']} backend, "
          f"{report['run_time_s'] / sc.n_steps * 1e6:.2f} us per step)")
    if report["max_rel_error"] is not None:
        print(f"error against the exact response (matrix exponential, max over time and "
              f"outputs, relative to max |x|): {report['max_rel_error']:.3e}")
    for what, path in (("results", args.out), ("plot", args.plot)):
        if path:
            print(f"{what}: {path}")
    return 0


def _stability(args) -> int:
    import numpy as np

    from dtdyn.generated import SCHEMES
    from dtdyn.linear.stability import critical_omega_dt, stability

    names = args.schemes or list(SCHEMES)
    omega = np.geomspace(1e-2, 1e3, 400)
    marks = [0.1, 0.5, 1.0, 10.0, 1000.0]
    print(f"{'scheme':22s} {'critical Omega':>14s}  " + "  ".join(f"rho({w:g})" for w in marks)
          + "  elongation(0.1)  damping(0.1)")
    curves = {}
    for name in names:
        st = stability(name, omega)
        at = stability(name, marks)
        crit = critical_omega_dt(name)
        curves[name] = st
        print(f"{name:22s} {crit:14.4f}  " + "  ".join(f"{r:8.4f}" for r in at.spectral_radius)
              + f"  {at.period_elongation[0]:15.3e}  {at.algorithmic_damping[0]:12.3e}")
    if args.plot:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(12, 4), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(1, 3)
        from matplotlib import colormaps

        colors = colormaps["tab20"](np.linspace(0, 1, 20))
        for i, (name, st) in enumerate(curves.items()):
            style = dict(label=name, color=colors[(2 * i) % 20 + (2 * i) // 20],
                         ls=("-", "--", ":")[i % 3])
            axes[0].semilogx(st.omega_dt, st.spectral_radius, **style)
            axes[1].loglog(st.omega_dt, np.abs(st.period_elongation), **style)
            axes[2].loglog(st.omega_dt, np.maximum(np.abs(st.algorithmic_damping), 1e-16), **style)
        for ax, title in zip(axes, ("spectral radius", "|period elongation|",
                                    "|algorithmic damping ratio|")):
            ax.set_title(title)
            ax.set_xlabel("Omega = omega dt")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].set_ylim(0, 1.5)
        axes[0].legend(fontsize=6)
        fig.savefig(args.plot, dpi=120)
        print(f"plot: {args.plot}")
    return 0


def _bench(args) -> int:
    from dtdyn.app import bench
    command = "dtdyn bench " + " ".join(args.problems) + (" --quick" if args.quick else "")
    bench.run(args.problems, args.out, quick=args.quick, command=command)
    return 0


def _srs(args) -> int:
    import warnings

    import numpy as np

    from dtdyn.modal import srs as S

    accel = S.load_record(args.record, args.column)
    if not args.dt > 0.0 or not np.isfinite(args.dt):
        raise ValueError(f"--dt must be finite and > 0, got {args.dt!r}")
    fs = 1.0 / args.dt
    if args.freqs is None:
        fmin, fmax, n = fs / 1e4, fs / 10.0, 100
    else:
        fmin, fmax, n = args.freqs
        if float(n) != int(n) or int(n) < 1:
            raise ValueError(f"--freqs: the count n must be an integer >= 1, got {n!r}")
        n = int(n)
        if not (0.0 < fmin and fmin <= fmax):
            raise ValueError(f"--freqs: need 0 < fmin <= fmax, got fmin = {fmin!r}, "
                             f"fmax = {fmax!r}")
    freqs = np.geomspace(fmin, fmax, n)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", S.SRSSamplingWarning)
        res = S.shock_response_spectrum(accel, args.dt, freqs, damping=args.damping,
                                        response=args.response, window=args.window,
                                        points_per_cycle=args.points_per_cycle,
                                        exact_peaks=args.exact_peaks)
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)
    info = res.info
    print(f"SRS of {args.record}: {accel.size} samples, dt = {args.dt:g} s (fs = {fs:g} Hz); "
          f"{args.response.replace('_', ' ')}, damping {args.damping:g} (Q = "
          f"{(1 / (2 * args.damping)) if args.damping > 0 else float('inf'):g}), "
          f"{args.window} window, {'exact' if args.exact_peaks else 'sampled'} peaks"
          + (f", upsampled x{info['upsample']}" if info["upsample"] > 1 else ""))
    rows = np.unique(np.linspace(0, n - 1, min(n, 12)).round().astype(int))
    print(f"{'f [Hz]':>12s} {'maximax':>13s} {'positive':>13s} {'negative':>13s}")
    for i in rows:
        print(f"{res.freqs[i]:12.5g} {res.maximax[i]:13.6g} {res.positive[i]:13.6g} "
              f"{res.negative[i]:13.6g}")
    k = int(np.argmax(res.maximax))
    print(f"largest: {res.maximax[k]:.6g} at {res.freqs[k]:.5g} Hz; run time "
          f"{(info['setup_time'] + info['run_time']) * 1e3:.1f} ms ({info['backend']})")
    if args.out:
        S.save_srs_csv(args.out, res)
        print(f"results: {args.out}")
    if args.plot:
        S.plot_srs(args.plot, res, title=f"SRS of {Path(args.record).name}, damping "
                                         f"{args.damping:g}, {args.window} window")
        print(f"plot: {args.plot}")
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="dtdyn", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    g = sub.add_parser("generate", help="rewrite generated/ from the SymPy derivations")
    g.add_argument("--check", action="store_true", help="exit 1 if generated/ is out of date")
    g.add_argument("--out", help="target folder (default: the package's generated/)")
    s = sub.add_parser("show", help="print a scheme's derived coefficients and transfer matrices")
    s.add_argument("scheme")
    r = sub.add_parser("simulate", help="run a scene (default: the embedded P3 benchmark)")
    r.add_argument("scene", nargs="?", help="scene TOML file")
    r.add_argument("--out", help="write results to this .npz file")
    r.add_argument("--plot", help="plot the displacements to this image file")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    st = sub.add_parser("stability", help="spectral radius, period elongation, damping per scheme")
    st.add_argument("schemes", nargs="*", help="scheme names (default: all)")
    st.add_argument("--plot", help="draw the curves to this image file")
    be = sub.add_parser("bench", help="work-precision report: error against run time per method")
    be.add_argument("problems", nargs="*", default=["P3", "P4"], help="P3, P4 (default: both)")
    be.add_argument("--out", default="bench", help="folder for the Markdown, JSON and plot")
    be.add_argument("--quick", action="store_true", help="shorter sweeps (a smoke run)")
    sr = sub.add_parser("srs", help="shock response spectrum of a base-acceleration record")
    sr.add_argument("record", help=".npy or .csv record of acceleration samples")
    sr.add_argument("--dt", type=float, required=True, help="sample step of the record, s")
    sr.add_argument("--freqs", type=float, nargs=3, metavar=("FMIN", "FMAX", "N"),
                    help="N log-spaced natural frequencies, Hz (default 1e-4/dt .. 0.1/dt, 100)")
    sr.add_argument("--damping", type=float, default=0.05, help="damping ratio (default 0.05)")
    sr.add_argument("--response", default="absolute_acceleration",
                    choices=["absolute_acceleration", "relative_displacement",
                             "relative_velocity", "pseudo_velocity", "pseudo_acceleration"])
    sr.add_argument("--window", default="total", choices=["total", "primary", "residual"])
    sr.add_argument("--points-per-cycle", type=float, default=None,
                    help="upsample linearly to at least this many samples per cycle")
    sr.add_argument("--exact-peaks", action="store_true", help="true peaks between samples")
    sr.add_argument("--column", type=int, default=-1,
                    help="column of a table holding the samples (default: the last)")
    sr.add_argument("--plot", help="draw maximax/positive/negative to this image file")
    sr.add_argument("--out", help="write freq_hz, maximax, positive, negative to this CSV")
    args = parser.parse_args(argv)
    handler = {"generate": _generate, "show": _show, "simulate": _simulate,
               "stability": _stability, "srs": _srs, "bench": _bench}[args.command]
    try:
        return handler(args)
    except (ValueError, FileNotFoundError, FloatingPointError) as exc:
        print(f"dtdyn {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
