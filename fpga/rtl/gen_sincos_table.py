#!/usr/bin/env python3
"""Generates fpga/rtl/sincos_table.hex, the committed quarter-wave sine table.

Run once; the output is committed and never regenerated at build or run time (floating-point sine
may differ in the last bit between machines; this script uses exact decimal arithmetic instead).

Entry i (0 <= i <= 4095), one line of 12 hex digits = a 46-bit word {T[i] (29 bits), D[i] (17 bits)}:
  T[i] = round_half_up(sin(i * (pi/2) / 4096) * 2^28)       unsigned <+,29,1>, LSB 2^-28
  D[i] = T[i+1] - T[i]  (i < 4096),  D[4096] = 0             unsigned <+,17,-11>, LSB 2^-28
No T value lies within 1e-30 of a rounding tie (checked below), so the rounding rule is moot.
The last point T[4096] = 2^28, D[4096] = 0 is not written: it is a constant of the model and of
the RTL, so the ROM is 4096 rows deep (a power of two; 4097 rows would take an 8192-row ROM).
"""
from decimal import Decimal, getcontext

getcontext().prec = 80
PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899")
N = 4096
SCALE = 2 ** 28


def sin(x: Decimal) -> Decimal:
    """Taylor series; |x| <= pi/2, so 60 terms are far more than enough at 80 digits."""
    term, total, k = x, x, 1
    while abs(term) > Decimal(10) ** -75:
        term = -term * x * x / ((2 * k) * (2 * k + 1))
        total += term
        k += 1
    return total


def main() -> None:
    t = []
    for i in range(N + 1):
        v = sin(PI / 2 * i / N) * SCALE
        frac = v - int(v)
        assert abs(frac - Decimal("0.5")) > Decimal(10) ** -30, f"tie at {i}"
        t.append(int(v + Decimal("0.5")))
    assert t[0] == 0 and t[N] == SCALE
    with open(__file__.replace("gen_sincos_table.py", "sincos_table.hex"), "w") as f:
        for i in range(N):
            d = t[i + 1] - t[i]
            assert 0 <= d < 2 ** 17 and 0 <= t[i] < 2 ** 29
            f.write("%012x\n" % ((t[i] << 17) | d))


if __name__ == "__main__":
    main()
