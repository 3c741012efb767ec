"""The `dtdyn` command: simulate scenes, shock response spectra, stability tables, benchmarks,
and (from a checkout, with the [derive] extra) regenerate and show the derived kernels."""
from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

from dtdyn._engine.public import warning_scope
from dtdyn.generated.scheme_table import TABLE as SCHEMES


def _checkout(start: Path) -> Path | None:
    """The dtdyn source checkout that holds ``start`` (a folder with derive/, generated/ and a
    pyproject.toml naming dtdyn), or None."""
    for folder in (start, *start.parents):
        pyproject = folder / "pyproject.toml"
        if (folder / "derive").is_dir() and (folder / "generated").is_dir() and \
                pyproject.is_file() and 'name = "dtdyn"' in pyproject.read_text():
            return folder
    return None


def _generate(args) -> int:
    from dtdyn._engine.extras import require
    require("sympy", "derive", "dtdyn generate")
    require("jinja2", "derive", "dtdyn generate")
    from dtdyn.derive import emit  # SymPy and jinja2: build time only

    if args.out:
        dest = Path(args.out)
    else:
        checkout = _checkout(Path.cwd())
        if checkout is None:
            raise ValueError("run `dtdyn generate` from inside a dtdyn source checkout (it writes "
                             "that checkout's generated/), or name the folder with --out")
        dest = checkout / "generated"
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
    if args.out:  # a copy for vendoring: the C with its headers, scheme files' kernels, example
        from dtdyn.derive import scheme_file

        schemes = [scheme_file.parse(path) for path in args.schemes]
        vendor = emit.write_vendor(dest / "vendor", schemes)
        print(f"wrote {len(vendor)} C sources and headers to {dest / 'vendor'} (each compiles "
              "there with `cc -O2 -c`; example.c shows a call)")
    elif args.schemes:
        raise ValueError("scheme files are written with --out DIR (a standalone copy); "
                         "without it `dtdyn generate` rewrites the checkout's generated/")
    return 0


def _show(args) -> int:
    """`dtdyn scheme show NAME|FILE` (and its alias `dtdyn show`): the derivation, readable."""
    from dtdyn._engine.extras import require
    require("sympy", "derive", "dtdyn scheme show")
    from dtdyn.app._derivation import derivation

    d = derivation(args.scheme)
    print(d.markdown() if args.markdown else d.latex() if args.latex else str(d), end="")
    return 0


def _scheme_ref(text: str):
    """A built-in scheme's name as it is, or the scheme of a scheme file (*.toml) loaded."""
    from dtdyn._engine.scheme_files import SHIPPED, load_scheme

    if text.endswith(".toml") or (SHIPPED / f"{text}.toml").is_file():
        return load_scheme(text)
    if text not in SCHEMES:
        raise ValueError(f"unknown scheme {text!r}; available: {', '.join(SCHEMES)}, or a scheme "
                         "file (*.toml)")
    return text


def _check(args) -> int:
    """`dtdyn scheme check NAME|FILE`: what the derivation found (order, explicitness, start-up,
    rho at infinity, stability limit), then `dtdyn stability`'s table (and --plot) for it."""
    import numpy as np

    from dtdyn.linear._stability import stability

    ref = _scheme_ref(args.scheme)
    row = ref.table if hasattr(ref, "table") else SCHEMES[ref]
    name = getattr(ref, "name", ref)
    claimed = row.get("claimed_order")
    how = ("derived from the local truncation error's Taylor series" if hasattr(ref, "table")
           else "of the built-in scheme")
    print(f"{row['title']} ({name})" + (f"; {row['reference']}" if row["reference"] else ""))
    if hasattr(ref, "path"):
        print(f"file: {ref.path} (sha256 {ref.sha256[:16]}; derived into {ref.folder})")
    print(f"order of accuracy: {row['order']} ({how}"
          + (f"; the file claims {claimed}, as derived" if claimed else "") + ")")
    def bound(v, inf):
        return inf if v is None else f"{v:g}"

    params = ", ".join(f"{p} = {v['default']:g} in [{bound(v['range'][0], '-inf')}, "
                       f"{bound(v['range'][1], 'inf')}]"
                       for p, v in row["params"].items()) or "none"
    print(f"parameters: {params}")
    print("explicit: acceleration form only" if row["explicit"] else
          "implicit: displacement and acceleration forms")
    if row["startup_steps"]:
        print(f"multistep: starts with {row['startup_steps']} steps of {row['startup_scheme']}")
    rho_inf = float(stability(ref, [1e8]).spectral_radius[0])
    print(f"spectral radius at Omega = 1e8 (rho_inf): {rho_inf:.6f}")
    args.schemes = [args.scheme]
    code = _stability(args)
    return code if np.isfinite(rho_inf) else 1


def _scheme(args) -> int:
    """`dtdyn scheme ACTION`: one handler per action."""
    return {"show": _show, "check": _check}[args.action](args)


def _simulate_nonlinear(args, sc) -> int:
    """`dtdyn simulate` of a scene with [[element]]: run, store, print times and Newton stats."""
    from dtdyn.app import _scene as scenes

    params = "".join(f", {k} = {v:g}" for k, v in sc.scheme_params.items())
    substeps = sc.nonlinear.get("substeps", 1)
    target = sc.nonlinear.get("accuracy")
    steps = (f"accuracy {target:g}" if target is not None
             else f"{substeps} substep(s) per sample")
    print(f"{sc.title}: {sc.n_dof} DOF, {sc.n_steps} steps of dt = {sc.dt:g} s, "
          f"{len(sc.elements)} nonlinear element(s), scheme {sc.scheme}{params} "
          f"({steps}, backend {sc.backend})")
    for k, el in enumerate(sc.elements):
        print(f"  element[{k}]: {el.describe()}")
    response, report = scenes.run_scene(sc)  # a failed run raises: main() says it, writes nothing
    if args.out:
        scenes.save_results(args.out, response, sc)
    if args.plot:
        scenes.plot_response(args.plot, response, sc)
    n_steps = sc.n_steps * report["substeps"] + 1  # as nonlinear_mck_response counts them
    if report["construct_time_s"] is not None:  # nonlinear_mck_response (matrices and chains)
        print(f"construct time: {report['construct_time_s'] * 1e3:.2f} ms, compile or cache "
              f"load: {report['compile_time_s'] * 1e3:.2f} ms, setup: "
              f"{report['setup_time_s'] * 1e3:.2f} ms")
    else:  # the DT-TMM sweep of a shaft or beam
        print(f"setup: {report['setup_time_s'] * 1e3:.2f} ms")
    per = (f"{report['run_time_s'] / n_steps * 1e6:.3f} us per step of h = dt / "
           f"{report['substeps']}" if target is None else "all the runs the target took")
    print(f"run time: {report['run_time_s'] * 1e3:.2f} ms ({report['backend']} backend, {per})")
    iters = report["newton_iterations"]
    its = ("not counted (casadi backend)" if iters is None
           else f"max {iters['max']}, mean {iters['mean']:.3f}"
           + (f", {iters['factorizations']} LU factorizations" if "factorizations" in iters
              else ""))
    print(f"Newton iterations per step: {its}; max residual: {report['max_residual']:.3e}")
    if report["error_estimate"] is not None:
        met = ("" if target is None else
               f"; accuracy {target:g} {'met' if report['accuracy_met'] else 'NOT met'}")
        print(f"error estimate: {report['error_estimate']:.3g} (relative; ran "
              f"{report['scheme']}, {report['substeps']} substep(s) per sample{met})")
    _print_written(args)
    return 0


def _print_written(args) -> None:
    """Say where --out (a CSV with its JSON metadata sidecar) and --plot went."""
    if args.out:
        from dtdyn._engine.result_io import sidecar_path
        extra = (f" (metadata: {sidecar_path(args.out)})"
                 if str(args.out).lower().endswith(".csv") else "")
        print(f"results: {args.out}{extra}")
    if args.plot:
        print(f"plot: {args.plot}")


def _check_outputs(args) -> None:
    """Refuse a bad --out or --plot path before the run (nothing is computed or written)."""
    from dtdyn._engine.result_io import check_result_path
    from dtdyn.app._scene.io import plot_checked_path

    if args.out:
        check_result_path(args.out)
    if args.plot:
        plot_checked_path(args.plot)


def _check_table_outputs(args) -> None:
    """`_check_outputs` for the commands whose --out is a CSV table (srs, fds, random)."""
    from dtdyn.app._scene.io import plot_checked_path

    if args.out and (Path(args.out).is_dir() or not Path(args.out).resolve().parent.is_dir()):
        raise ValueError(f"--out {args.out!r}: not a file in an existing folder")
    if args.plot:
        plot_checked_path(args.plot)


def _simulate(args) -> int:
    from dtdyn.app import _scene as scenes

    _check_outputs(args)
    sc = scenes.load_scene(args.scene)
    sc.require_run("dtdyn simulate")
    if not sc.linear:
        for flag, used in (("--no-check", args.no_check), ("--quiet", args.quiet)):
            if used:
                raise ValueError(f"{flag} applies to linear scenes only (a nonlinear run has no "
                                 "exact check and no progress bar)")
        if args.unstable is not None:
            raise ValueError(f"--unstable {args.unstable} applies to linear scenes only (a "
                             "nonlinear run checks each step's stability as it runs)")
        return _simulate_nonlinear(args, sc)
    if args.unstable is not None:  # the flag overrides the scene's scheme.unstable
        import dataclasses
        sc = dataclasses.replace(sc, unstable=args.unstable)
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
        from dtdyn._engine.schemes import get_scheme
        from dtdyn.linear._solver import schemes_of_run

        for part in schemes_of_run(get_scheme(sc.scheme)):   # a composite's stages
            kernels.c_chain_function(part)
        print(f"C kernel compile or cache load: {time.perf_counter() - t0:.3f} s")
    long_run = sc.n_steps * sc.n_dof > 5e7
    if not args.no_check:
        print("checking against the exact response (matrix exponential) after the run; "
              "--no-check skips it")
    response, report = scenes.run_scene(sc, progress=long_run and not args.quiet,
                                        check=not args.no_check)
    if args.out:
        scenes.save_results(args.out, response, sc)
    if args.plot:
        scenes.plot_response(args.plot, response, sc)
    print(f"run time: {report['run_time_s'] * 1e3:.2f} ms ({response.info['backend']} backend, "
          f"{report['run_time_s'] / sc.n_steps * 1e6:.2f} us per step)")
    if report["max_rel_error"] is not None:
        print(f"error against the exact response (max over time and outputs, relative to "
              f"max |x|): {report['max_rel_error']:.3e} (check took "
              f"{report['exact_time_s'] * 1e3:.1f} ms)")
    elif not args.no_check:
        print(f"exact check {report['check']}")
    _print_written(args)
    return 0


#: |algorithmic damping| or |period elongation| below this is round-off of the eigenvalue
#: computation, not a property of the scheme (printed as 0, not drawn)
NOISE_FLOOR = 1e-12


def _stability(args) -> int:
    import numpy as np

    from dtdyn.linear._stability import critical_omega_dt, stability

    refs = [_scheme_ref(n) for n in args.schemes] or list(SCHEMES)
    if args.plot:
        from dtdyn.app._scene.io import plot_checked_path
        plot_checked_path(args.plot)
    omega = np.geomspace(1e-2, 1e3, 400)
    marks = [0.1, 0.5, 1.0, 10.0, 1000.0]

    def clean(v):  # round-off below the floor: exactly 0
        v = np.asarray(v, dtype=float)
        return np.where(np.abs(v) < NOISE_FLOOR, 0.0, v)

    print(f"{'scheme':22s} {'critical Omega':>14s}  " + "  ".join(f"rho({w:g})" for w in marks)
          + "  elongation(0.1)  damping(0.1)")
    curves = {}
    for ref in refs:
        name = getattr(ref, "name", ref)
        st = stability(ref, omega)
        at = stability(ref, marks)
        crit = critical_omega_dt(ref)
        curves[name] = st
        print(f"{name:22s} {crit:14.4f}  " + "  ".join(f"{r:8.4f}" for r in at.spectral_radius)
              + f"  {clean(at.period_elongation)[0]:15.3e}  "
              f"{clean(at.algorithmic_damping)[0]:12.3e}")
    print(f"(|values| below {NOISE_FLOOR:g} are round-off and shown as 0)")
    if args.plot:
        from matplotlib import colormaps
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        fig = Figure(figsize=(12, 4.2), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(1, 3)
        colors = colormaps["tab20"](np.linspace(0, 1, 20))
        markers = "os^vD<>ph*XP"
        for i, (name, st) in enumerate(curves.items()):
            style = dict(label=name, color=colors[(2 * i) % 20 + (2 * i) // 20],
                         ls=("-", "--", ":")[i % 3], marker=markers[i % len(markers)],
                         markevery=40, ms=3)
            axes[0].semilogx(st.omega_dt, st.spectral_radius, **style)
            for ax, values in ((axes[1], st.period_elongation), (axes[2], st.algorithmic_damping)):
                shown = np.abs(clean(values))
                ax.loglog(st.omega_dt, np.where(shown > 0, shown, np.nan), **style)
        for ax, title in zip(axes, ("spectral radius", "|period elongation|",
                                    "|algorithmic damping ratio| (0 not drawn)")):
            ax.set_title(title)
            ax.set_xlabel("Omega = omega dt")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].set_ylim(0, 1.5)
        axes[0].legend(fontsize=6)
        fig.savefig(args.plot, dpi=120)
        print(f"plot: {args.plot}")
    return 0


#: dense eigenproblems up to this many DOFs when --count is not given
MODES_DENSE_MAX = 2000


def _modes(args) -> int:
    import json

    import numpy as np
    import scipy.sparse as sps

    from dtdyn.app import _scene as scenes
    from dtdyn.modal._modes import mck_modes

    sc = scenes.load_scene(args.scene)
    if sc.model is not None:  # a kind in MODEL_MODULES: its own frequencies (Wittrick-Williams)
        from dtdyn.app._scene.schema import model_module

        omega = model_module(sc.kind).frequencies(sc.model, args.count)
        if args.json:
            print(json.dumps({"scene": sc.title, "n_dof": sc.n_dof, "kind": sc.kind,
                              "method": "Wittrick-Williams", "omega_rad_s": omega.tolist(),
                              "frequency_hz": (omega / (2 * np.pi)).tolist()}))
            return 0
        print(f"{sc.title}: {sc.kind}, {sc.n_dof} DOF, {omega.size} frequencies "
              "(Wittrick-Williams count)")
        print(f"{'mode':>4s} {'f [Hz]':>12s} {'omega [rad/s]':>14s}")
        for r, w in enumerate(omega):
            print(f"{r + 1:4d} {w / (2 * np.pi):12.6g} {w:14.6g}")
        return 0
    M, C, K = sc.matrices()
    n = sc.n_dof
    if args.count is not None and not 1 <= args.count <= n:
        raise ValueError(f"--count {args.count}: must be 1 .. {n} (the DOFs of the scene)")
    if sps.issparse(M) and (args.count is None or args.count >= n):
        if n > MODES_DENSE_MAX:
            raise ValueError(f"{n} DOFs: give --count N (< {n}) for the lowest modes by "
                             "shift-invert")
        M, C, K = (A.toarray() for A in (M, C, K))
    damped = not sps.issparse(C) and np.any(C)
    m = mck_modes(M, C if damped else None, K, count=args.count)
    if args.json:
        print(json.dumps({"scene": sc.title, "n_dof": n, **m.to_dict()}))
        return 0
    print(f"{sc.title}: {n} DOF, {m.omega.size} mode(s); participation for the influence "
          f"vector of ones, total mass {m.total_mass:.6g}")
    head = f"{'mode':>4s} {'f [Hz]':>12s} {'omega [rad/s]':>14s} {'T [s]':>11s}"
    head += f" {'zeta':>9s}" if damped else ""
    print(head + f" {'Gamma':>11s} {'m_eff':>11s} {'m_eff %':>8s} {'cum. %':>7s}")
    cum = np.cumsum(m.effective_mass_ratio) * 100
    for r in range(m.omega.size):
        row = f"{r + 1:4d} {m.frequency_hz[r]:12.6g} {m.omega[r]:14.6g} {m.period[r]:11.5g}"
        row += f" {m.damping_ratio[r]:9.4g}" if damped else ""
        print(row + f" {m.participation[r]:11.4g} {m.effective_mass[r]:11.4g} "
              f"{m.effective_mass_ratio[r] * 100:8.3f} {cum[r]:7.2f}")
    return 0


def _spectrum(args) -> int:

    import numpy as np

    from dtdyn._engine.atomic import write_atomic
    from dtdyn.app._scene.schema import STANDARD_GRAVITY
    from dtdyn.modal._spectrum import default_periods, response_spectrum
    from dtdyn.modal._srs import load_record

    if args.out and (Path(args.out).is_dir() or not Path(args.out).resolve().parent.is_dir()):
        raise ValueError(f"--out {args.out!r}: not a file in an existing folder")
    ag = load_record(args.record, args.column)
    if args.units == "g":
        ag = ag * STANDARD_GRAVITY
    if not args.dt > 0.0 or not np.isfinite(args.dt):
        raise ValueError(f"--dt must be finite and > 0, got {args.dt!r}")
    if args.periods is None:  # those the record resolves: from max(0.02 s, 10 dt) to 5 s
        periods = default_periods(args.dt)
    else:
        tmin, tmax, n = args.periods
        if float(n) != int(n) or int(n) < 1 or not 0.0 < tmin <= tmax:
            raise ValueError(f"--periods: need 0 < TMIN <= TMAX and an integer N >= 1, got "
                             f"{tmin!r} {tmax!r} {n!r}")
        periods = np.geomspace(tmin, tmax, int(n))
    s = response_spectrum(ag, args.dt, periods, damping_ratio=args.damping_ratio)
    print(f"response spectra of {args.record}: {ag.size} samples, dt = {args.dt:g} s, peak "
          f"ground acceleration {np.abs(ag).max():.4g} m/s^2; SD [m], PSV [m/s], PSA and SA "
          f"[m/s^2]; {s.info['run_time'] * 1e3:.1f} ms")
    rows = np.unique(np.linspace(0, periods.size - 1, min(periods.size, 12)).round().astype(int))
    lines = ["damping_ratio,period_s,sd_m,psv_m_s,psa_m_s2,sa_m_s2"]
    for i, zeta in enumerate(s.damping_ratio):
        print(f"damping ratio {zeta:g}:\n{'T [s]':>10s} {'SD':>12s} {'PSV':>12s} {'PSA':>12s} "
              f"{'SA':>12s}")
        for j in rows:
            print(f"{periods[j]:10.4g} {s.sd[i, j]:12.5g} {s.psv[i, j]:12.5g} "
                  f"{s.psa[i, j]:12.5g} {s.sa[i, j]:12.5g}")
        lines += [",".join(repr(float(v)) for v in (zeta, periods[j], s.sd[i, j], s.psv[i, j],
                                                     s.psa[i, j], s.sa[i, j]))
                  for j in range(periods.size)]
    if args.out:
        write_atomic(args.out, lambda fh: fh.write(("\n".join(lines) + "\n").encode()))
        print(f"results: {args.out}")
    return 0


def _batch(args) -> int:
    """`dtdyn batch`: many cases on Dask (run_batch), a progress bar and a summary; exit 1 when
    a case failed (the store is written all the same)."""
    import json

    from dtdyn._engine.extras import require
    from dtdyn.app._batch import CBackendError, run_batch

    client = None
    if args.scheduler:  # argparse refuses --workers with it
        distributed = require("distributed", "batch", "dtdyn batch")
        client = distributed.Client(args.scheduler, timeout="30s")
    try:
        ds = run_batch(args.scenes, vary=args.vary, seed=args.seed, client=client,
                       workers=args.workers, reduce=args.reduce, out=args.out,
                       chunk=args.chunk if args.chunk is not None else "auto",
                       progress=not args.quiet, check=not args.no_check,
                       overwrite=args.overwrite, unstable=args.unstable, resume=args.resume,
                       rerun_failed=args.rerun_failed, case_timeout=args.case_timeout)
    except CBackendError as exc:
        print(f"dtdyn batch: error: {exc}", file=sys.stderr)
        return 2
    finally:
        if client is not None:
            client.close()
    summary = json.loads(ds.attrs["dtdyn_batch"])["summary"]
    if args.quiet:
        print(f"{summary['cases']} cases: {summary['done']} done, {summary['failed']} failed; "
              f"wall time {summary['wall_time_s']:.2f} s, {summary['cases_per_s']:.1f} cases/s"
              + (f"; {summary['skipped']} finished before (resumed)"
                 if summary.get("skipped") else ""))
    print(f"results: {args.out}")
    return 1 if summary["failed"] else 0


def _bench(args) -> int:
    from dtdyn.app import _bench as bench
    command = ("dtdyn bench " + " ".join(args.problems) + (" --quick" if args.quick else "")
               + (f" --blas-threads {args.blas_threads}" if args.blas_threads != 1 else ""))
    bench.run(args.problems, args.out, quick=args.quick, command=command,
              blas_threads=args.blas_threads)
    return 0


def _srs(args) -> int:

    import numpy as np

    from dtdyn.modal import _srs as S

    accel = S.load_record(args.record, args.column)
    _check_table_outputs(args)
    if not args.dt > 0.0 or not np.isfinite(args.dt):
        raise ValueError(f"--dt must be finite and > 0, got {args.dt!r}")
    fs = 1.0 / args.dt
    if args.freqs is None:
        # 10 samples per cycle at fs / 10: sampled peaks low by at most 1 - cos(pi/10) = 4.9 %,
        # below the 5 % of SRSSamplingWarning (dtdyn.modal._srs)
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
    res = S.shock_response_spectrum(accel, args.dt, freqs, damping_ratio=args.damping_ratio,
                                    response=args.response, window=args.window,
                                    points_per_cycle=args.points_per_cycle,
                                    exact_peaks=args.exact_peaks)
    info = res.info
    print(f"SRS of {args.record}: {accel.size} samples, dt = {args.dt:g} s (fs = {fs:g} Hz); "
          f"{args.response.replace('_', ' ')}, damping ratio {args.damping_ratio:g} (Q = "
          f"{(1 / (2 * args.damping_ratio)) if args.damping_ratio > 0 else float('inf'):g}), "
          f"{args.window} window, {'exact' if args.exact_peaks else 'sampled'} peaks"
          + (f", upsampled x{info['upsample']}" if info["upsample"] > 1 else ""))
    rows = np.unique(np.linspace(0, n - 1, min(n, 12)).round().astype(int))
    print(f"{'f [Hz]':>12s} {'maximax':>13s} {'positive':>13s} {'negative':>13s}")
    for i in rows:
        print(f"{res.freqs_hz[i]:12.5g} {res.maximax[i]:13.6g} {res.positive[i]:13.6g} "
              f"{res.negative[i]:13.6g}")
    k = int(np.argmax(res.maximax))
    print(f"largest: {res.maximax[k]:.6g} at {res.freqs_hz[k]:.5g} Hz; run time "
          f"{(info['setup_time'] + info['run_time']) * 1e3:.1f} ms ({info['backend']})")
    if args.out:
        S.save_srs_csv(args.out, res)
        print(f"results: {args.out}")
    if args.plot:
        S.plot_srs(args.plot, res, title=f"SRS of {Path(args.record).name}, damping ratio "
                                         f"{args.damping_ratio:g}, {args.window} window")
        print(f"plot: {args.plot}")
    return 0


def _read_psd_table(path):
    """A PSD table from a CSV of two columns, f [Hz] and G [(unit)^2/Hz] (one header line
    allowed), log-log between its rows."""
    import numpy as np

    from dtdyn.random_vibration._psd import psd_table

    try:
        data = np.loadtxt(path, delimiter=",", ndmin=2)
    except ValueError:
        data = np.loadtxt(path, delimiter=",", ndmin=2, skiprows=1)
    if data.shape[1] != 2 or data.shape[0] < 2:
        raise ValueError(f"{path}: expected two columns (f [Hz], PSD) and at least two rows, "
                         f"got a table of shape {data.shape}")
    return psd_table([(float(f), float(g)) for f, g in data])


def _fds(args) -> int:
    """`dtdyn fds`: the VRS, ERS and FDS of a PSD table (and the PSD equivalent to the FDS
    over a test duration), printed, saved as CSV + JSON sidecar and plotted."""
    import json

    import numpy as np

    from dtdyn._engine.atomic import write_atomic_files
    from dtdyn._engine.result_io import _versions, sidecar_path
    from dtdyn.random_vibration import _spectra as S

    _check_table_outputs(args)
    table = _read_psd_table(args.psd)
    if args.q is not None:
        if not args.q > 0.5 or not np.isfinite(args.q):
            raise ValueError(f"--q must be finite and > 0.5 (damping ratio 1 / (2 Q) < 1), "
                             f"got {args.q!r}")
        zeta = 1.0 / (2.0 * args.q)
    else:
        zeta = 0.05 if args.damping_ratio is None else args.damping_ratio
    if args.freqs is None:
        fmin, fmax, n = float(table.freqs_hz[0]), float(table.freqs_hz[-1]), 100
    else:
        fmin, fmax, n = args.freqs
        if float(n) != int(n) or int(n) < 1 or not 0.0 < fmin <= fmax:
            raise ValueError(f"--freqs: need 0 < FMIN <= FMAX and an integer N >= 1, got "
                             f"{fmin!r} {fmax!r} {n!r}")
    f_n = np.geomspace(fmin, fmax, int(n))
    vrs = S.vibration_response_spectrum(table, f_n, zeta)
    ers = S.extreme_response_spectrum(table, f_n, zeta, duration=args.duration)
    fds = S.fatigue_damage_spectrum(table, f_n, zeta, slope=args.slope,
                                    coefficient=args.coefficient, duration=args.duration,
                                    response=args.response, method=args.method)
    test = None if args.test_duration is None else S.fds_equivalent_psd(fds, args.test_duration)
    print(f"spectra of {args.psd}: {table.grms:.4g} grms over {table.freqs_hz[0]:g} .. "
          f"{table.freqs_hz[-1]:g} Hz; damping ratio {zeta:g} (Q = {1 / (2 * zeta):g}), "
          f"duration {args.duration:g} s; VRS and ERS of the absolute and pseudo "
          f"acceleration, FDS of the {args.response.replace('_', ' ')} (slope "
          f"{args.slope:g}, coefficient {args.coefficient:g}, {args.method.replace('_', ' ')})")
    head = f"{'f_n [Hz]':>12s} {'VRS':>12s} {'ERS':>12s} {'FDS':>12s}"
    print(head + (f" {'test PSD':>12s}" if test is not None else ""))
    for i in np.unique(np.linspace(0, f_n.size - 1, min(f_n.size, 12)).round().astype(int)):
        print(f"{f_n[i]:12.5g} {vrs.values[i]:12.5g} {ers.values[i]:12.5g} "
              f"{fds.values[i]:12.5g}" + (f" {test.values[i]:12.5g}" if test is not None
                                          else ""))
    if test is not None:
        print(f"PSD equivalent to the FDS over {args.test_duration:g} s: {test.grms:.4g} grms "
              f"({test.grms / table.grms:.4g} x the input)")
    if args.out:
        cols = [f_n, vrs.values, ers.values, fds.values] + ([test.values] if test else [])
        names = ["freq_hz", "vrs", "ers", "fds"] + (["test_psd"] if test else [])
        lines = [",".join(names)] + [",".join(f"{v:.17g}" for v in row)
                                     for row in np.column_stack(cols)]
        data = ("\n".join(lines) + "\n").encode()
        meta = {"format": "dtdyn test spectra", "version": 1, "table": Path(args.out).name,
                "columns": names, "psd_file": str(args.psd),
                "psd_breakpoints": [[float(f), float(g)] for f, g in
                                    zip(table.freqs_hz, table.values)],
                "psd_grms": table.grms, "damping_ratio": zeta, "duration_s": args.duration,
                "vrs": {"response": vrs.response,
                        "rms_error_estimate": vrs.info["rms_error_estimate"]},
                "ers": {"response": ers.response, "peak": ers.info["peak"]},
                "fds": {"response": fds.response, "slope": args.slope,
                        "coefficient": args.coefficient, "method": args.method},
                "test_duration_s": args.test_duration,
                "test_psd_grms": None if test is None else test.grms,
                "versions": _versions()}
        side = (json.dumps(meta, indent=1) + "\n").encode()
        write_atomic_files([(sidecar_path(args.out), lambda fh: fh.write(side)),
                            (args.out, lambda fh: fh.write(data))])
        print(f"results: {args.out} (metadata: {sidecar_path(args.out).name})")
    if args.plot:
        fig, save = _figure(args.plot, (7.0, 9.0))
        a1, a2, a3 = fig.subplots(3, 1)
        fb = np.geomspace(table.freqs_hz[0], table.freqs_hz[-1], 400)
        a1.loglog(fb, table(fb), "k", label=f"{Path(args.psd).name}: {table.grms:.3g} grms")
        if test is not None:
            a1.loglog(f_n, test.values, "r--", label=f"FDS-equivalent over "
                                                      f"{args.test_duration:g} s: "
                                                      f"{test.grms:.3g} grms")
        a1.set(xlabel="f [Hz]", ylabel="PSD [(unit)^2/Hz]")
        a2.loglog(f_n, vrs.values, label="VRS (rms absolute acceleration)")
        a2.loglog(f_n, ers.values, label=f"ERS (pseudo-acceleration, {args.duration:g} s)")
        a2.set(xlabel="natural frequency [Hz]", ylabel="response")
        a3.loglog(f_n, fds.values, label=f"FDS, slope {args.slope:g}, {args.duration:g} s")
        a3.set(xlabel="natural frequency [Hz]", ylabel="damage")
        for ax in (a1, a2, a3):
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=8)
        fig.suptitle(f"damping ratio {zeta:g} (Q = {1 / (2 * zeta):g})", fontsize=10)
        save()
    return 0


def _figure(plot, figsize):
    """A figure for ``--plot`` (its format checked first) and the function that writes it
    atomically and says where."""
    from dtdyn._engine.atomic import write_atomic
    from dtdyn.app._scene.io import plot_checked_path

    path, fmt = plot_checked_path(plot)
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, layout="constrained")

    def save():
        write_atomic(path, lambda fh: fig.savefig(fh, format=fmt, dpi=110))
        print(f"plot: {plot}")
    return fig, save


def _fds_arguments(sub) -> None:
    """The parser of `dtdyn fds`."""
    from dtdyn.random_vibration._fatigue import METHODS
    from dtdyn.random_vibration._spectra import RESPONSES

    fd = sub.add_parser("fds", help="vibration response, extreme response and fatigue damage "
                                    "spectra (VRS, ERS, FDS) of a PSD table, and the PSD "
                                    "equivalent to its FDS over a test duration")
    fd.add_argument("psd", help="CSV of the PSD table: two columns, f [Hz] and PSD "
                                "[(unit)^2/Hz], log-log between rows")
    fd.add_argument("--slope", type=float, required=True,
                    help="Basquin slope b of the S-N curve N = C S^-b")
    fd.add_argument("--coefficient", type=float, default=1.0,
                    help="Basquin coefficient C (default 1)")
    fd.add_argument("--duration", type=float, required=True, help="exposure time, s")
    damping = fd.add_mutually_exclusive_group()
    damping.add_argument("--q", type=float, default=None,
                         help="quality factor Q = 1 / (2 damping ratio) (default 10)")
    damping.add_argument("--damping-ratio", type=float, default=None,
                         help="damping ratio (default 0.05)")
    fd.add_argument("--freqs", type=float, nargs=3, metavar=("FMIN", "FMAX", "N"),
                    help="N log-spaced natural frequencies, Hz (default: the table's band, 100)")
    fd.add_argument("--response", default="relative_displacement", choices=RESPONSES,
                    help="the response whose damage the FDS sums (default relative "
                         "displacement)")
    fd.add_argument("--method", default="narrow_band", choices=METHODS,
                    help="spectral damage formula (default narrow_band)")
    fd.add_argument("--test-duration", type=float, default=None, metavar="SECONDS",
                    help="also give the PSD whose FDS over this duration equals the input's")
    fd.add_argument("--plot", help="draw the PSD (grms in the legend), VRS, ERS and FDS on "
                                   "log-log axes to this image file")
    fd.add_argument("--out", help="write freq_hz, vrs, ers, fds (, test_psd) to this CSV, "
                                  "its parameters to <name>.csv.json")


def _random_model(sc, table, freqs, quantities):
    """The RandomResponse of a scene's linear model under ``table``: at its [ground] as the
    support's acceleration PSD, else at each loaded DOF (independent loads, each the table's
    PSD); and what the input was, for the printout."""
    from dtdyn.random_vibration import chain_random_response, random_response

    if sc.ground is not None:
        load = {"ground_acceleration_psd": table, "influence": sc.influence}
        how = "support acceleration ([ground])"
    elif sc.loaded is not None and len(sc.loaded):
        load = {"psd": [table] * len(sc.loaded), "force_dofs": list(sc.loaded)}
        how = ("independent loads at DOF(s) "
               + ", ".join(sc.dof_label(d) for d in sc.loaded) + " ([[load]])")
    else:
        raise ValueError(f"{sc.source}: dtdyn random applies the PSD at the scene's loaded DOFs "
                         "([[load]] dof) or at its support ([ground]); the scene has neither")
    psd = load.pop("psd", None)
    common = {"outputs": list(sc.outputs), "quantities": quantities, **load}
    if sc.kind == "chain":
        return chain_random_response(sc.mass, sc.stiffness, sc.damping, psd, freqs,
                                     ground_stiffness=sc.ground_stiffness,
                                     ground_damping=sc.ground_damping, **common), how
    M, C, K = sc.matrices()
    if C is None:
        raise ValueError(f"{sc.source}: the model has no damping: the response PSDs of an "
                         "undamped model have infinite peaks")
    return random_response(M, C, K, psd, freqs, **common), how


def _random(args) -> int:
    """`dtdyn random SCENE --psd table.csv`: the response PSDs and rms of a scene's linear
    model under a PSD table (random_response), printed, saved as CSV + JSON sidecar and
    plotted."""
    import json

    import numpy as np

    from dtdyn._engine.atomic import write_atomic_files
    from dtdyn._engine.result_io import _versions, sidecar_path
    from dtdyn.app import _scene as scenes

    _check_table_outputs(args)
    table = _read_psd_table(args.psd)
    sc = scenes.load_scene(args.scene)
    if args.freqs is None:
        fmin, fmax, n = float(table.freqs_hz[0]), float(table.freqs_hz[-1]), 200
    else:
        fmin, fmax, n = args.freqs
        if float(n) != int(n) or int(n) < 2 or not 0.0 < fmin < fmax:
            raise ValueError(f"--freqs: need 0 < FMIN < FMAX and an integer N >= 2, got "
                             f"{fmin!r} {fmax!r} {n!r}")
    freqs = np.geomspace(fmin, fmax, int(n))
    quantities = tuple(q for q in sc.quantities if q in ("x", "v", "a")) or ("x",)
    r, how = _random_model(sc, table, freqs, quantities)
    labels = [sc.dof_label(d) for d in r.outputs]
    print(f"{sc.title}: {sc.n_dof} DOF ({sc.kind}), linear model"
          + (f" (its {len(sc.elements)} nonlinear element(s) left out)" if sc.elements else "")
          + f"; input {args.psd}: {table.grms:.4g} grms over {table.freqs_hz[0]:g} .. "
          f"{table.freqs_hz[-1]:g} Hz, as {how}")
    print(f"band {freqs[0]:g} .. {freqs[-1]:g} Hz; rms error estimate "
          f"{r.info['rms_error_estimate']:.1e} ({r.info['n_integration_freqs']} frequencies "
          "integrated)")
    print(f"{'output':>10s} " + " ".join(f"{'rms ' + q:>13s}" for q in r.quantities)
          + f" {'zero-up/s ' + r.quantities[0]:>12s}")
    for j, label in enumerate(labels):
        print(f"{label:>10s} " + " ".join(f"{r.rms[q][j]:13.6g}" for q in r.quantities)
              + f" {r.zero_crossing_rate[r.quantities[0]][j]:12.5g}")
    if args.out:
        names = ["freq_hz", "input_psd"] + [f"{q}_psd {label}" for q in r.quantities
                                            for label in labels]
        cols = [freqs, table(freqs)] + [np.real(getattr(r, f"{q}_psd")[:, j, j])
                                        for q in r.quantities for j in range(len(labels))]
        lines = [",".join(names)] + [",".join(f"{v:.17g}" for v in row)
                                     for row in np.column_stack(cols)]
        data = ("\n".join(lines) + "\n").encode()
        meta = {"format": "dtdyn random response", "version": 1, "table": Path(args.out).name,
                "columns": names, "scene": sc.source, "title": sc.title,
                "input": r.info["input"], "psd_file": str(args.psd),
                "psd_breakpoints": [[float(f), float(g)] for f, g in
                                    zip(table.freqs_hz, table.values)],
                "psd_grms": table.grms, "outputs": labels,
                "rms": {q: r.rms[q].tolist() for q in r.quantities},
                **{f"m{k}": {q: getattr(r, f"m{k}")[q].tolist() for q in r.quantities}
                   for k in (0, 1, 2, 4)},
                "rms_error_estimate": r.info["rms_error_estimate"],
                "n_integration_freqs": r.info["n_integration_freqs"],
                "modes_hz": np.asarray(r.info["modes_hz"]).tolist(),
                "damping_ratio": np.asarray(r.info["damping_ratio"]).tolist(),
                "versions": _versions()}
        side = (json.dumps(meta, indent=1) + "\n").encode()
        write_atomic_files([(sidecar_path(args.out), lambda fh: fh.write(side)),
                            (args.out, lambda fh: fh.write(data))])
        print(f"results: {args.out} (metadata: {sidecar_path(args.out).name})")
    if args.plot:
        fig, save = _figure(args.plot, (7.0, 2.8 * (len(r.quantities) + 1)))
        axes = fig.subplots(len(r.quantities) + 1, 1, squeeze=False)[:, 0]
        axes[0].loglog(freqs, table(freqs), "k",
                       label=f"{Path(args.psd).name}: {table.grms:.3g} grms")
        axes[0].set(xlabel="f [Hz]", ylabel="input PSD [(unit)^2/Hz]")
        for ax, q in zip(axes[1:], r.quantities):
            G = getattr(r, f"{q}_psd")
            for j, label in enumerate(labels):
                ax.loglog(freqs, np.real(G[:, j, j]),
                          label=f"{q} {label}: {r.rms[q][j]:.3g} rms")
            ax.set(xlabel="f [Hz]", ylabel=f"{q} PSD [(unit)^2/Hz]")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        fig.suptitle(f"{sc.title}: response PSDs", fontsize=10)
        save()
    return 0


def _random_arguments(sub) -> None:
    """The parser of `dtdyn random`."""
    ra = sub.add_parser("random", help="response PSDs and rms of a scene's linear model under a "
                                       "PSD table (at its loaded DOFs, or its [ground])")
    ra.add_argument("scene", metavar="SCENE", help="scene TOML file")
    ra.add_argument("--psd", required=True,
                    help="CSV of the PSD table: two columns, f [Hz] and PSD [(unit)^2/Hz], "
                         "log-log between rows; applied at each [[load]] DOF (independent "
                         "loads), or as the support's acceleration when the scene has [ground]")
    ra.add_argument("--freqs", type=float, nargs=3, metavar=("FMIN", "FMAX", "N"),
                    help="N log-spaced frequencies where the PSDs are returned, Hz (default: "
                         "the table's band, 200); the rms integrates FMIN .. FMAX")
    ra.add_argument("--plot", help="draw the input and response PSDs on log-log axes (grms and "
                                   "rms in the legends) to this image file")
    ra.add_argument("--out", help="write freq_hz, the input PSD and each output's PSD per "
                                  "quantity to this CSV, the rms and moments to <name>.csv.json")


def _amplitudes(F) -> str:
    """A load's amplitudes for the printout: numbers, complex ones as re+imj."""
    import numpy as np

    def one(z):
        return f"{z.real:g}" if z.imag == 0 else f"{z.real:g}{z.imag:+g}j"
    F = np.atleast_1d(F)
    return ", ".join(one(z) for z in F) if F.ndim == 1 else \
        "; ".join("harmonics [" + ", ".join(one(z) for z in row) + "]" for row in F)


def _steady(args) -> int:
    """`dtdyn steady SCENE`: the periodic steady state of a scene's [harmonic] table
    (harmonic_balance), a summary, --out (.npz or .csv) and --plot (unstable parts dashed)."""
    from dtdyn._engine.curve_io import check_curve_path
    from dtdyn.app._scene import load_scene, steady
    from dtdyn.app._scene.io import plot_checked_path

    if args.out:
        check_curve_path(args.out)
    if args.plot:
        plot_checked_path(args.plot)
    sc = load_scene(args.scene)
    steady.require_harmonic(sc, "dtdyn steady")
    kw = sc.harmonic
    span = (f"{kw['freqs_hz'][0]:g} .. {kw['freqs_hz'][1]:g} Hz" if "freqs_hz" in kw else
            f"load factor {kw['amplitudes'][0]:g} .. {kw['amplitudes'][1]:g} at "
            f"{kw['frequency_hz']:g} Hz")
    print(f"{sc.title}: {sc.kind}, {sc.n_dof} DOF, {len(sc.elements)} nonlinear element(s); "
          f"harmonic balance with H = {kw['harmonics']} harmonics over {span}")
    for k, el in enumerate(sc.elements):
        print(f"  element[{k}]: {el.describe()}")
    if "force" in kw:
        for d, F in zip(kw["force_dofs"], kw["force"]):
            print(f"  force on DOF {sc.dof_label(d)}: {_amplitudes(F)}")
    if "ground_acceleration" in kw:
        print(f"  ground acceleration: {_amplitudes(kw['ground_acceleration'][0])}")
    r, report = steady.run_steady(sc, "dtdyn steady")
    if args.out:
        steady.save_steady(args.out, r, sc)
    if args.plot:
        steady.plot_steady(args.plot, r, sc)
    _steady_summary(r, report, sc)
    _print_written(args)
    return 0


def _steady_summary(r, report, sc) -> None:
    """What `dtdyn steady` prints after the run."""
    import numpy as np

    amplitude = report["sweep"] == "amplitude"
    folds = report["fold_amplitude"] if amplitude else report["fold_frequency_hz"]
    where = (", ".join(f"{f:.6g}" for f in folds) + (" (load factor)" if amplitude else " Hz")
             if folds else "none")
    print(f"points: {report['n_points']} ({report['stop']}); folds: {where}")
    kinds = getattr(r, "bifurcation_kind", None)   # folds, Neimark-Sacker, branch points
    if kinds is not None:
        at = r.bifurcation_amplitude if amplitude else r.bifurcation_frequency_hz
        unit = " (load factor)" if amplitude else " Hz"
        other = [f"{k} at {a:.6g}{unit}" for k, a in zip(kinds, at) if k != "fold"]
        print("other bifurcations: " + (", ".join(other) or "none"))
    if r.stable is not None:
        n_stable = int(np.count_nonzero(r.stable))
        print(f"stable: {n_stable} of {r.stable.size} points ({100 * n_stable / r.stable.size:.1f} "
              "%, Hill's method)")
    else:
        print("stability: not computed (harmonic.stability = false)")
    err = report["harmonic_error"]
    if err is not None and np.isfinite(err):
        print(f"harmonic truncation estimate: {err:.2e} (the last two kept harmonics, relative "
              "to the largest max |x|)")
    conv = r.info.get("harmonic_convergence")   # the check from H to 2 H, where it was run
    if isinstance(conv, float) and np.isfinite(conv):
        failed = r.info.get("harmonic_convergence_failures") or 0
        print(f"harmonic convergence (H to 2 H): {conv:.2e}"
              + (f", {failed} point(s) not solved with 2 H" if failed else ""))
    for j, d in enumerate(r.outputs[:8]):
        i = int(np.argmax(r.x_max[:, j]))
        at = (f"load factor {r.amplitude[i]:.6g}" if amplitude else
              f"{r.frequency_hz[i]:.6g} Hz")
        print(f"  largest max |x| of DOF {sc.dof_label(d)}: {r.x_max[i, j]:.6g} at {at}")
    if len(r.outputs) > 8:
        print(f"  ... and {len(r.outputs) - 8} more outputs")
    print(f"run time: {report['run_time_s']:.3f} s ({report['receptance']} receptance, "
          f"{r.info.get('steps')} steps, {r.info.get('newton_iterations')} Newton iterations)")


def _steady_arguments(sub) -> None:
    """The parser of `dtdyn steady`."""
    st = sub.add_parser("steady", help="periodic steady state of a scene with [[element]] and "
                                       "[harmonic] tables: the frequency response curve by "
                                       "harmonic balance, its folds and stability")
    st.add_argument("scene", metavar="SCENE", help="scene TOML file with a [harmonic] table")
    st.add_argument("--out", help="write the curve: .npz, or .csv (one row per point) with its "
                                  "metadata in <name>.csv.json; dtdyn.load_result reads it back")
    st.add_argument("--plot", help="draw max |x| of each output against the frequency, unstable "
                                   "parts dashed, to this image file (.png, .pdf, ...)")


def _show_arguments(p) -> None:
    """The arguments of `dtdyn scheme show` and of its alias `dtdyn show`."""
    p.add_argument("scheme", metavar="SCHEME",
                   help=f"a built-in scheme ({', '.join(SCHEMES)}) or a scheme file (*.toml)")
    how = p.add_mutually_exclusive_group()
    how.add_argument("--latex", action="store_true", help="print LaTeX (amsmath align*)")
    how.add_argument("--markdown", action="store_true", help="print Markdown with $...$ math")


def _parser() -> argparse.ArgumentParser:
    from dtdyn import __version__
    from dtdyn.modal._srs import RESPONSES, WINDOWS

    parser = argparse.ArgumentParser(
        prog="dtdyn", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="`dtdyn COMMAND --help` describes a command. Names follow one vocabulary: "
               "--dt is the sample step in seconds, schemes are named as in `dtdyn show`.")
    parser.add_argument("--version", action="version", version=f"dtdyn {__version__}")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    r = sub.add_parser("simulate", help="run a scene (default: the embedded P3 scene) and check "
                                        "it against the exact response")
    r.add_argument("scene", nargs="?", help="scene TOML file")
    r.add_argument("--out", help="write the results: .npz, .nc (netCDF) or .csv (a plain table "
                                 "with a 't [s]' column, its metadata in <name>.csv.json)")
    r.add_argument("--plot", help="plot the stored quantities to this image file (.png, .pdf, ...)")
    r.add_argument("--no-check", action="store_true",
                   help="skip the comparison with the exact response (matrix exponential)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--unstable", choices=["raise", "warn"], default=None,
                   help="a dt past the scheme's stability limit: stop (raise) or run it anyway "
                        "with a warning, for study (default: the scene's scheme.unstable, "
                        "else raise)")
    mo = sub.add_parser("modes", help="natural frequencies, participation factors and effective "
                                      "masses of a scene's model (damping ratios when it has C)")
    mo.add_argument("scene", nargs="?", help="scene TOML file (default: the embedded P3 scene)")
    mo.add_argument("--count", type=int, default=None, help="the lowest N modes (default: all)")
    mo.add_argument("--json", action="store_true", help="print the modes as JSON (for scripts)")
    sp = sub.add_parser("spectrum", help="earthquake response spectra (SD, PSV, PSA, SA) of a "
                                         "ground acceleration record")
    sp.add_argument("record", help=".npy or .csv record of ground acceleration samples")
    sp.add_argument("--dt", type=float, required=True, help="sample step of the record, s")
    sp.add_argument("--periods", type=float, nargs=3, default=None,
                    metavar=("TMIN", "TMAX", "N"),
                    help="N log-spaced periods, s (default: 60 from max(0.02, 10 dt) to 5, the "
                         "periods the record resolves: at least 10 samples per period)")
    sp.add_argument("--damping-ratio", type=float, nargs="+", default=[0.05],
                    help="damping ratios (default 0.05)")
    sp.add_argument("--damping", type=float, nargs="+", dest="damping_ratio",
                    default=argparse.SUPPRESS, help=argparse.SUPPRESS)  # the old name
    sp.add_argument("--units", choices=["m/s^2", "g"], default="m/s^2",
                    help="unit of the record (g: times 9.80665)")
    sp.add_argument("--column", type=int, default=None,
                    help="column of a table holding the samples (default: the last)")
    sp.add_argument("--out", help="write damping ratio, period and the four spectra to "
                                         "this CSV")
    sr = sub.add_parser("srs", help="shock response spectrum of a base-acceleration record")
    sr.add_argument("record", help=".npy or .csv record of acceleration samples")
    sr.add_argument("--dt", type=float, required=True, help="sample step of the record, s")
    sr.add_argument("--freqs", type=float, nargs=3, metavar=("FMIN", "FMAX", "N"),
                    help="N log-spaced natural frequencies, Hz (default 1e-4/dt .. 0.1/dt, 100)")
    sr.add_argument("--damping-ratio", type=float, default=0.05,
                    help="damping ratio (default 0.05)")
    sr.add_argument("--damping", type=float, dest="damping_ratio", default=argparse.SUPPRESS,
                    help=argparse.SUPPRESS)  # the old name
    sr.add_argument("--response", default="absolute_acceleration", choices=RESPONSES)
    sr.add_argument("--window", default="total", choices=WINDOWS)
    sr.add_argument("--points-per-cycle", type=float, default=None,
                    help="upsample linearly to at least this many samples per cycle")
    sr.add_argument("--exact-peaks", action="store_true", help="true peaks between samples")
    sr.add_argument("--column", type=int, default=None,
                    help="column of a table holding the samples (default: the last)")
    sr.add_argument("--plot", help="draw maximax/positive/negative to this image file")
    sr.add_argument("--out", help="write freq_hz, maximax, positive, negative to this CSV")
    _fds_arguments(sub)
    _random_arguments(sub)
    _steady_arguments(sub)
    st = sub.add_parser("stability", help="spectral radius, period elongation and algorithmic "
                                          "damping of each scheme")
    st.add_argument("schemes", nargs="*", metavar="SCHEME",
                    help=f"scheme names (default: all): {', '.join(SCHEMES)}, or scheme files "
                         "(*.toml)")
    st.add_argument("--plot", help="draw the curves to this image file")
    ba = sub.add_parser("batch", help="run many scenes or variations of one on Dask (this machine "
                                      "or a cluster) into a Zarr store (needs the [batch] extra)")
    ba.add_argument("scenes", nargs="+", metavar="SCENE", help="scene TOML files")
    ba.add_argument("--vary", metavar="TABLE.csv",
                    help="a CSV table of variations: a header of dotted keys (model.stiffness[2], "
                         "load[0].seed, ground.path, ground.scale, ...), one row per case, "
                         "applied to every SCENE")
    ba.add_argument("--seed", type=int, default=None,
                    help="root seed: per-case seeds of the white-noise loads from "
                         "SeedSequence(seed).spawn")
    where = ba.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="worker processes of a local cluster (default: one per CPU)")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    ba.add_argument("--reduce", default=None,
                    help="keep reductions instead of time histories: a comma-separated list of "
                         "peak, rms, drift, srs, welch, history")
    ba.add_argument("--out", required=True, help="the Zarr store to write (results.zarr)")
    ba.add_argument("--chunk", type=int, default=None, help="cases per task (default: auto)")
    ba.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    ba.add_argument("--resume", action="store_true",
                    help="continue an existing --out: run only its cases not yet done (the "
                         "same cases, reducers and dtdyn version, else an error says what "
                         "differs); without a store, start it")
    ba.add_argument("--rerun-failed", action="store_true",
                    help="with --resume: run the store's failed cases again too")
    ba.add_argument("--case-timeout", type=float, default=None, metavar="SECONDS",
                    help="fail a case that runs longer than this (TimeoutError) and restart "
                         "its worker, instead of waiting for it (default: no limit)")
    ba.add_argument("--no-check", action="store_true",
                    help="skip the comparison of linear cases with the exact response")
    ba.add_argument("--quiet", action="store_true", help="no progress bar")
    ba.add_argument("--unstable", choices=["raise", "warn"], default=None,
                    help="linear cases whose dt is past the scheme's stability limit: fail "
                         "(raise) or run anyway with a warning (default: each scene's "
                         "scheme.unstable, else raise)")
    be = sub.add_parser("bench", help="work-precision report: error against run time per method")
    be.add_argument("problems", nargs="*", default=["P3", "P4"], choices=["P3", "P4"],
                    help="P3, P4 (default: both)")
    be.add_argument("--out", default="bench", help="folder for the Markdown, JSON and plot")
    be.add_argument("--quick", action="store_true", help="shorter sweeps (a smoke run)")
    be.add_argument("--blas-threads", type=int, default=1, metavar="N",
                    help="threads of the BLAS libraries during the bench (threadpoolctl; "
                         "default 1: small matrices' BLAS calls on several threads of a shared "
                         "machine vary by 50x from run to run)")
    sc = sub.add_parser("scheme", help="a time-integration scheme: `dtdyn scheme show NAME` "
                                       "prints its derivation")
    actions = sc.add_subparsers(dest="action", required=True, metavar="ACTION")
    show_help = ("a scheme's defining relations, derived coefficients and DT-TMM station "
                 "matrices, factored (needs the [derive] extra)")
    _show_arguments(actions.add_parser("show", help=show_help))
    _show_arguments(sub.add_parser("show", help=show_help + "; the same as `dtdyn scheme show`"))
    ck = actions.add_parser("check", help="a scheme's derivation report: order of accuracy, "
                                          "explicitness, rho_inf, stability limit, spectral "
                                          "radius and period elongation over Omega")
    ck.add_argument("scheme", metavar="SCHEME",
                    help=f"a built-in scheme ({', '.join(SCHEMES)}), a shipped scheme file "
                         "(bathe, rho_inf_bathe) or a scheme file (*.toml)")
    ck.add_argument("--plot", help="draw spectral radius, period elongation and algorithmic "
                                   "damping over Omega to this image file")
    g = sub.add_parser("generate", help="rewrite generated/ from the SymPy derivations (from a "
                                        "source checkout; needs the [derive] extra)")
    g.add_argument("--check", action="store_true", help="exit 1 if generated/ is out of date")
    g.add_argument("--out", help="target folder (default: generated/ of the checkout you are "
                                 "in); with --out, also DIR/vendor: the C kernels, their headers "
                                 "and example.c, standalone")
    g.add_argument("schemes", nargs="*", metavar="SCHEME_FILE",
                   help="scheme files (TOML) whose kernels --out adds to DIR/vendor")
    return parser


def _warning_line(command: str):
    """A `warnings.showwarning` that prints one line, ``dtdyn <command>: warning: <Category>:
    <message>``, instead of a source path and line the user did not write."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"dtdyn {command}: warning: {category.__name__}: {message}",
              file=file or sys.stderr)
    return show


def main(argv=None) -> int:
    """Run the `dtdyn` command; returns the exit code (0 ok, 1 a failed run or check, 2 bad
    input or a result too large for memory, 3 an internal error, 130 Ctrl-C). Errors are one
    line on stderr (``--debug`` shows the traceback)."""
    from dtdyn._engine.errors import (DtdynAccuracyWarning, DtdynFallbackWarning,
                                      DtdynStabilityWarning, DtdynStepStabilityError,
                                      DtdynUnstableError, NewtonError, SingularMassError,
                                      SRSSamplingWarning)

    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version (0) or a usage error (2), already printed
        return int(exc.code or 0)
    handler = {"generate": _generate, "show": _show, "scheme": _scheme, "simulate": _simulate,
               "stability": _stability, "srs": _srs, "fds": _fds, "random": _random,
               "steady": _steady,
               "bench": _bench,
               "modes": _modes, "spectrum": _spectrum, "batch": _batch}[args.command]
    try:
        with warning_scope(), warnings.catch_warnings():
            for category in (DtdynStabilityWarning, DtdynAccuracyWarning, SRSSamplingWarning,
                             DtdynFallbackWarning):   # each shown (once per command: warn)
                warnings.simplefilter("always", category)
            warnings.showwarning = _warning_line(args.command)
            return handler(args)
    except BrokenPipeError:  # `dtdyn ... | head`: stop quietly, no traceback at exit either
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except (NewtonError, DtdynStepStabilityError, DtdynUnstableError, FloatingPointError) as exc:
        if args.debug:
            raise
        print(f"dtdyn {args.command}: run failed: {exc}", file=sys.stderr)
        return 1
    except (ValueError, SingularMassError, OSError, ImportError, MemoryError) as exc:
        if args.debug:
            raise
        print(f"dtdyn {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: C loops stop within a second, nothing is written
        if args.debug:
            raise
        print(f"dtdyn {args.command}: interrupted; nothing was written", file=sys.stderr)
        return 130
    except Exception as exc:  # a defect of dtdyn: still one line, the traceback on --debug
        if args.debug:
            raise
        print(f"dtdyn {args.command}: internal error ({type(exc).__name__}: {exc}); rerun with "
              "--debug for the traceback and report it", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
