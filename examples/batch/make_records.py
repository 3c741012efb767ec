"""Write 50 synthetic ground acceleration records and the table of variations for
`dtdyn batch` (docs/batch.md): records/gm_000.csv .. gm_049.csv (2,001 samples at dt = 0.01 s,
in g) and records.csv (columns ground.path, ground.scale).

Each record is white noise (seed = its number) through a second-order filter (Kanai-Tajimi
like: ground frequency 2.5 Hz, damping 0.6) under a trapezoidal envelope (rise 2 s, strong
motion to 8 s, exponential decay), scaled to a peak ground acceleration of 0.1 g to 0.4 g.

    python examples/batch/make_records.py [FOLDER] [--count N] [--samples N]
"""
import argparse
from pathlib import Path

import numpy as np
import scipy.signal


def record(seed: int, n: int, dt: float, pga: float) -> np.ndarray:
    """One record in g: filtered, enveloped white noise of peak ``pga``."""
    t = np.arange(n) * dt
    noise = np.random.default_rng(seed).standard_normal(n)
    wg, zg = 2 * np.pi * 2.5, 0.6
    num, den = [2 * zg * wg, wg**2], [1.0, 2 * zg * wg, wg**2]
    _, ag, _ = scipy.signal.lsim((num, den), noise, t)
    env = np.minimum(t / 2.0, 1.0) * np.where(t > 8.0, np.exp(-0.5 * (t - 8.0)), 1.0)
    ag = ag * env
    return pga * ag / np.abs(ag).max()


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", nargs="?", default=str(Path(__file__).parent))
    parser.add_argument("--count", type=int, default=50)
    parser.add_argument("--samples", type=int, default=2001)
    args = parser.parse_args(argv)
    folder = Path(args.folder)
    (folder / "records").mkdir(parents=True, exist_ok=True)
    rows = ["ground.path,ground.scale"]
    for i in range(args.count):
        name = f"records/gm_{i:03d}.csv"
        pga = 0.1 + 0.3 * i / max(args.count - 1, 1)
        np.savetxt(folder / name, record(i, args.samples, 0.01, pga), fmt="%.10g")
        rows.append(f"{name},1.0")
    (folder / "records.csv").write_text("\n".join(rows) + "\n")
    print(f"{args.count} records and records.csv in {folder}")


if __name__ == "__main__":
    main()
