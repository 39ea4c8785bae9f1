"""The Python Robotics Toolbox side of `scripts/bench-kinematics`.

Times the same PUMA 560 calls as `drivers/benches/kinematics.rs` with the toolbox
(`roboticstoolbox-python`), reads criterion's estimates for the Rust side, and prints a ratio
table. With `--reference` it prints the toolbox values hard-coded in
`drivers/tests/model_reference.rs` instead.
"""

import argparse
import json
import os
import platform
import statistics
import sys
import timeit
import warnings

import numpy as np

warnings.filterwarnings("ignore")
import roboticstoolbox as rtb  # noqa: E402

Q = np.array([0.3, -0.4, 0.7, -1.1, 0.9, 0.5])
QD = np.array([0.2, -0.5, 0.3, 1.0, -0.7, 0.4])
QDD = np.array([1.0, 0.5, -0.8, 0.3, 0.2, -1.5])
CONFIGS = ["lun", "luf", "ldn", "ldf", "run", "ruf", "rdn", "rdf"]


def reference(p):
    np.set_printoptions(precision=17, linewidth=250, floatmode="unique")
    qn = p.qn
    print("fkine(qn)", repr(p.fkine(qn).A))
    print("fkine(q)", repr(p.fkine(Q).A))
    print("jacob0(q)", repr(p.jacob0(Q)))
    print("jacobe(q)", repr(p.jacobe(Q)))
    print("gravload(qn)", repr(p.gravload(qn)))
    print("gravload(q)", repr(p.gravload(Q)))
    print("inertia(qn)", repr(p.inertia(qn)))
    print("inertia(q)", repr(p.inertia(Q)))
    print("nofriction().rne(q, qd, qdd)", repr(p.nofriction(True, True).rne(Q, QD, QDD)))
    print("friction(qd)", repr(p.friction(QD)))
    T = p.fkine(Q)
    for c in CONFIGS:
        s = p.ikine_a(T, c)
        print("ikine_a", c, s.success, repr(s.q))


def per_call(fn, target_seconds=0.4, repeat=7):
    """Median seconds per call over `repeat` runs of about `target_seconds` each."""
    n, t = 1, 0.0
    while t < 0.05:
        t = timeit.timeit(fn, number=n)
        n *= 2
    number = max(1, int(n / 2 * target_seconds / max(t, 1e-9)))
    runs = timeit.repeat(fn, number=number, repeat=repeat)
    return statistics.median(r / number for r in runs)


def criterion_ns(criterion_dir, bench):
    path = os.path.join(criterion_dir, "puma560", bench, "new", "estimates.json")
    with open(path) as f:
        est = json.load(f)
    return est["median"]["point_estimate"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reference", action="store_true")
    ap.add_argument("--criterion-dir", default="target/criterion")
    args = ap.parse_args()
    p = rtb.models.DH.Puma560()
    if args.reference:
        reference(p)
        return
    pn = p.nofriction(True, True)
    T = p.fkine(Q)
    rows = [
        # (label, criterion id, toolbox call, toolbox description)
        ("fk", "fk", lambda: p.fkine(Q), "fkine(q)"),
        ("jacobian (base)", "jacobian", lambda: p.jacob0(Q), "jacob0(q)"),
        ("fk + jacobian", "fk+jacobian", lambda: (p.fkine(Q), p.jacob0(Q)), "fkine + jacob0"),
        ("fk + jacobian, one pass", "fk+jacobian one pass", lambda: (p.fkine(Q), p.jacob0(Q)), "fkine + jacob0"),
        ("ik, all 8 branches", "ik all 8 branches", lambda: [p.ikine_a(T, c) for c in CONFIGS], "ikine_a x 8 configs"),
        ("ik, branch nearest a seed", "ik near seed", lambda: [p.ikine_a(T, c) for c in CONFIGS], "ikine_a x 8 configs"),
        ("ik numerical (DLS vs LM)", "ik numerical (DLS)", lambda: p.ikine_LM(T, q0=Q + 0.05), "ikine_LM(T, q0)"),
        ("gravity", "gravity", lambda: p.gravload(Q), "gravload(q)"),
        ("inertia", "inertia", lambda: p.inertia(Q), "inertia(q)"),
        ("rne", "rne", lambda: pn.rne(Q, QD, QDD), "rne(q, qd, qdd)"),
    ]
    print(
        f"PUMA 560, per call, median. Python {platform.python_version()}, "
        f"roboticstoolbox {rtb.__version__}, numpy {np.__version__}"
    )
    try:
        from threadpoolctl import threadpool_info

        blas = [
            f"{i.get('internal_api')} {i.get('version')} ({i.get('architecture')})"
            for i in threadpool_info()
        ]
        print("numpy BLAS:", ", ".join(blas) or "none loaded")
    except ImportError:
        pass
    print()
    header = f"| {'call':<26} | {'Penelope (Rust)':>15} | {'Robotics Toolbox':>16} | {'toolbox call':<20} | {'ratio':>8} |"
    print(header)
    print("|" + "|".join("-" * (len(c)) for c in header.split("|")[1:-1]) + "|")
    for label, bench, fn, desc in rows:
        try:
            ns = criterion_ns(args.criterion_dir, bench)
        except FileNotFoundError:
            print(f"missing criterion result for {bench}", file=sys.stderr)
            sys.exit(1)
        py_ns = per_call(fn) * 1e9
        print(
            f"| {label:<26} | {fmt(ns):>15} | {fmt(py_ns):>16} | {desc:<20} | {py_ns / ns:>7.0f}x |"
        )


def fmt(ns):
    return f"{ns:.0f} ns" if ns < 10_000 else f"{ns / 1000:.1f} µs"


if __name__ == "__main__":
    main()
