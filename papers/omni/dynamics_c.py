"""A control tick's sub-steps of :class:`papers.omni.dynamics.OmniDynamics` in compiled C.

:meth:`OmniDynamics.apply` cuts each tick into ``substeps`` sub-steps, each a box-constrained
QP on 4-element arrays (:func:`papers.omni.dynamics.coulomb_forces`); in numpy that is
interpreter overhead, ≈ 0.4 ms per tick. The C function :data:`SOURCE` runs the same sub-step
loop for a four-wheel platform (the servo law or the held torques, Coriolis, ``s_free``, the
all-stick case through ``A⁻¹`` and the active-set fallback) with the same operations in the
same order as the Python loop (``OmniDynamics._python_substeps``, the test's referee).

The small matrix–vector products and the free block's solve are written in the order (and
with the fused multiply-adds) numpy's OpenBLAS kernels use on x86-64 with FMA for these shapes
(measured: ``(k, m) @ (m,)`` with ``k ≥ 2`` rows sums ``m = 2`` as ``fma(a0, x0, a1 x1)``,
``m = 3`` as ``fma(a2, x2, fma(a0, x0, a1 x1))``, ``m = 4`` as
``(a0 x0 + a2 x2) + (a1 x1 + a3 x3)``; one row is a forward fused chain; ``Gᵀ F`` is
``fma(g0, F0, g1 F1) + fma(g2, F2, g3 F3)``; ``np.linalg.solve`` is LAPACK's ``dgesv`` as
OpenBLAS computes it, see ``solve``). The results are then bitwise those of the Python loop in
nearly every sub-step; not always, because OpenBLAS's order for some shapes depends on where
numpy placed the operands in memory (measured: ``(2, 2) @ (2,)``, the bound wheels' coupling
in the active set), so the Python loop itself is bitwise reproducible only up to that. Where
they differ, they agree to round-off (≈ 1e-16 relative, ``tests/test_omni_dynamics_c.py``);
on another BLAS or CPU likewise.

The library is built once per machine by the system compiler (``$CC``) into
:mod:`wbc.cbuild`'s cache; :func:`library` returns ``None`` — and the plant keeps its Python
loop — when there is no compiler or the build fails.
"""

from __future__ import annotations

import ctypes
from functools import cache

import numpy as np

from wbc import cbuild

# nothing for the package to re-export: OmniDynamics (papers.omni.dynamics) is the public face
__all__: list[str] = []

SOURCE = r"""
#include <math.h>

#define N 4  /* wheels */

/* y = M x, M (rows, m) row-major, in numpy's (OpenBLAS's) summation order for m <= 4 */
static void matvec(int rows, int m, const double* M, const double* x, double* y) {
  for (int r = 0; r < rows; r++) {
    const double* a = M + r * m;
    double s;
    if (m == 0) {
      s = 0.0;
    } else if (rows == 1) {
      s = a[0] * x[0];
      for (int j = 1; j < m; j++) s = fma(a[j], x[j], s);
    } else if (m == 1) {
      s = a[0] * x[0];
    } else if (m == 2) {
      s = fma(a[0], x[0], a[1] * x[1]);
    } else if (m == 3) {
      s = fma(a[2], x[2], fma(a[0], x[0], a[1] * x[1]));
    } else {
      s = (a[0] * x[0] + a[2] * x[2]) + (a[1] * x[1] + a[3] * x[3]);
    }
    y[r] = s;
  }
}

/* x = M⁻¹ b for the (k, k) row-major M (overwritten), b overwritten by x: LAPACK's dgesv as
   numpy's OpenBLAS computes it — a left-looking LU with partial pivoting (getf2: each column
   gets the earlier row swaps, then its dot products with L as fused chains, the pivot's
   reciprocal scales L's column), then the swaps on b, L's and U's column-wise fused updates and
   a division by U's diagonal (trsv) */
static void solve(int k, double* M, double* b) {
  int pivot[N];
  for (int j = 0; j < k; j++) {
    for (int i = 0; i < j; i++) {
      if (pivot[i] != i) {
        double t = M[i * k + j]; M[i * k + j] = M[pivot[i] * k + j]; M[pivot[i] * k + j] = t;
      }
    }
    for (int i = 1; i < k; i++) {  /* rows above j: L's triangle; below: the whole L so far */
      int length = i < j ? i : j;
      double s = 0.0;
      for (int c = 0; c < length; c++) s = fma(M[i * k + c], M[c * k + j], s);
      if (length > 0) M[i * k + j] = M[i * k + j] - s;
    }
    int p = j;
    for (int i = j + 1; i < k; i++) if (fabs(M[i * k + j]) > fabs(M[p * k + j])) p = i;
    pivot[j] = p;
    double reciprocal = 1.0 / M[p * k + j];
    if (p != j) {
      for (int c = 0; c <= j; c++) {
        double t = M[j * k + c]; M[j * k + c] = M[p * k + c]; M[p * k + c] = t;
      }
    }
    for (int i = j + 1; i < k; i++) M[i * k + j] *= reciprocal;
  }
  for (int i = 0; i < k; i++) {
    if (pivot[i] != i) { double t = b[i]; b[i] = b[pivot[i]]; b[pivot[i]] = t; }
  }
  for (int i = 0; i < k; i++) {
    for (int r = i + 1; r < k; r++) b[r] = fma(-b[i], M[r * k + i], b[r]);
  }
  for (int i = k - 1; i >= 0; i--) {
    b[i] = b[i] / M[i * k + i];
    for (int r = 0; r < i; r++) b[r] = fma(-b[i], M[r * k + i], b[r]);
  }
}

static double sign_of(double x) { return x > 0.0 ? 1.0 : x < 0.0 ? -1.0 : 0.0; }

/* coulomb_forces (papers/omni/dynamics.py): F and slip; 0, or 1 if the loop did not settle */
static int coulomb(const double* A, const double* A_inv, const double* s_free,
                   const double* limit, double* F, double* slip) {
  double AF[N];
  matvec(N, N, A_inv, s_free, F);
  int inside = 1;
  for (int i = 0; i < N; i++) inside &= fabs(F[i]) <= limit[i];
  if (inside) {
    matvec(N, N, A, F, AF);
    for (int i = 0; i < N; i++) slip[i] = s_free[i] - AF[i];
    return 0;
  }
  int bound[N];
  double sign[N], limit_max = limit[0], s_max = fabs(s_free[0]);
  for (int i = 0; i < N; i++) {
    bound[i] = limit[i] <= 0.0;
    sign[i] = 0.0;
    if (limit[i] > limit_max) limit_max = limit[i];
    if (fabs(s_free[i]) > s_max) s_max = fabs(s_free[i]);
  }
  double force_tol = 1e-12 * (1.0 + limit_max), slip_tol = 1e-12 * (1.0 + s_max);
  for (int iteration = 0; iteration < 8 * N; iteration++) {
    int free_i[N], bound_i[N], k = 0, m = 0;
    for (int i = 0; i < N; i++) {
      F[i] = bound[i] ? sign[i] * limit[i] : 0.0;
      if (bound[i]) bound_i[m++] = i; else free_i[k++] = i;
    }
    if (k > 0) {  /* A[free][:, free] F[free] = s_free[free] - A[free][:, bound] F[bound] */
      double Aff[N * N], Afb[N * N], Fb[N], rhs[N];
      for (int a = 0; a < k; a++) {
        for (int c = 0; c < k; c++) Aff[a * k + c] = A[free_i[a] * N + free_i[c]];
        for (int c = 0; c < m; c++) Afb[a * m + c] = A[free_i[a] * N + bound_i[c]];
      }
      for (int c = 0; c < m; c++) Fb[c] = F[bound_i[c]];
      matvec(k, m, Afb, Fb, rhs);
      for (int a = 0; a < k; a++) rhs[a] = s_free[free_i[a]] - rhs[a];
      solve(k, Aff, rhs);
      for (int a = 0; a < k; a++) F[free_i[a]] = rhs[a];
    }
    matvec(N, N, A, F, AF);
    for (int i = 0; i < N; i++) slip[i] = s_free[i] - AF[i];
    double excess[N], excess_max = 0.0;
    for (int i = 0; i < N; i++) {
      excess[i] = bound[i] ? 0.0 : fabs(F[i]) - limit[i];
      if (i == 0 || excess[i] > excess_max) excess_max = excess[i];
    }
    if (excess_max > force_tol) {
      int worst = 0;
      double worst_ratio = 0.0;
      for (int i = 0; i < N; i++) {
        double ratio = excess[i] / (limit[i] > 1e-300 ? limit[i] : 1e-300);
        if (i == 0 || ratio > worst_ratio) { worst = i; worst_ratio = ratio; }
      }
      bound[worst] = 1;
      sign[worst] = sign_of(F[worst]);
      continue;
    }
    int worst = 0;
    double wrong_max = 0.0;
    for (int i = 0; i < N; i++) {
      double wrong = bound[i] && sign[i] != 0.0 ? -sign[i] * slip[i] : 0.0;
      if (i == 0 || wrong > wrong_max) { worst = i; wrong_max = wrong; }
    }
    if (wrong_max <= slip_tol) return 0;
    bound[worst] = 0;
    sign[worst] = 0.0;
  }
  return 1;
}

/* the tick's sub-steps (OmniDynamics._python_substeps): servo = 0 holds the torques tau_in;
   otherwise the angle servos track command (angles since the tick's start [rad]); v (3),
   rates and integral are updated in place; turned, slid, peak and torque_sum (zeroed by the
   caller) accumulate. Returns 0, or 1 if an active-set loop did not settle. */
int wbc_omni_substeps(int substeps, int servo, double h, double inertia, double kp, double kv,
                      double ki, const double* R, const double* G, const double* M_inv,
                      const double* A, const double* A_inv, const double* limit,
                      const double* safe_limit, const double* gain, const double* noise,
                      const double* command, double* v, double* rates, double* integral,
                      double* turned, double* slid, double* peak, double* torque_sum) {
  double tau[N], drive[N], F[N], slip[N], Gw[N], w[3], coriolis[3], GtF[3], MG[3];
  if (!servo) {
    for (int i = 0; i < N; i++) {
      tau[i] = command[i];
      drive[i] = h * R[i] * tau[i] / inertia;
    }
  }
  for (int step = 0; step < substeps; step++) {
    if (servo) {
      for (int i = 0; i < N; i++) {
        double error = command[i] - turned[i];
        integral[i] += error * h;
        tau[i] = gain[i] * (kp * error - kv * rates[i] + ki * integral[i]) + noise[i];
        drive[i] = h * R[i] * tau[i] / inertia;
      }
    }
    coriolis[0] = v[2] * v[1];
    coriolis[1] = -v[2] * v[0];
    coriolis[2] = 0.0;
    for (int j = 0; j < 3; j++) w[j] = v[j] + h * coriolis[j];
    matvec(N, 3, G, w, Gw);
    double s_free[N];
    for (int i = 0; i < N; i++) s_free[i] = R[i] * rates[i] + drive[i] - Gw[i];
    if (coulomb(A, A_inv, s_free, limit, F, slip)) return 1;
    for (int i = 0; i < N; i++) rates[i] = rates[i] + h * (tau[i] - R[i] * F[i]) / inertia;
    for (int j = 0; j < 3; j++) {  /* (Gᵀ F)_j in numpy's order for the transposed G */
      GtF[j] = fma(G[0 * 3 + j], F[0], G[1 * 3 + j] * F[1])
               + fma(G[2 * 3 + j], F[2], G[3 * 3 + j] * F[3]);
    }
    matvec(3, 3, M_inv, GtF, MG);
    for (int j = 0; j < 3; j++) v[j] = v[j] + h * (coriolis[j] + MG[j]);
    for (int i = 0; i < N; i++) {
      turned[i] += h * rates[i];
      slid[i] += h * fabs(slip[i]);
      double use = fabs(F[i]) / safe_limit[i];
      peak[i] = use > peak[i] ? use : peak[i];
      torque_sum[i] += tau[i];
    }
  }
  return 0;
}
"""

# no contracted multiply-adds: only the explicit fma() calls fuse, as numpy's kernels do
FLAGS = ("-O2", "-ffp-contract=off", "-std=c11")


@cache
def library():
    """The compiled ``wbc_omni_substeps`` (a ``ctypes`` function; it returns 0, or 1 if an
    active-set loop did not settle), or ``None`` when it cannot be built or loaded here (the
    plant's Python loop then runs the same sub-steps). Built once per machine, loaded once per
    process."""
    try:
        function = ctypes.CDLL(str(cbuild.cached_library("omni_substeps", SOURCE, FLAGS,
                                                         ("-lm",)))).wbc_omni_substeps
    except (RuntimeError, OSError):
        return None
    array = np.ctypeslib.ndpointer(dtype=np.float64, flags="C_CONTIGUOUS")
    integer, real = ctypes.c_int, ctypes.c_double
    function.argtypes = [integer, integer, real, real, real, real, real, *[array] * 17]
    function.restype = integer
    return function
