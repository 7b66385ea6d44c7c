"""A control period's physics sub-steps of :class:`~wbc.sim.MujocoPlant` in compiled C.

The plant advances ``dt / TIMESTEP`` MuJoCo steps (1 ms) per control period; the Python loop
adds ≈ 1 µs (a held command) to ≈ 5 µs (acceleration commands: inverse dynamics) of
interpreter and numpy work to each step (MuJoCo's own ≈ 40 µs on the mecanum base with its 48
rollers, measured on one core). The C function :data:`SOURCE` runs the same sub-step loop with
the same MuJoCo calls in the same order (the states are bitwise those of the Python loop,
``MujocoPlant._python_substeps``), for the periods whose servo targets are known at the
period's start (all but a steered base's velocity and acceleration commands, whose targets
follow the steering angles sub-step by sub-step). Per sub-step ``k``:

1. the drive servos' targets: ``ctrl[drive_u] = drives[k]`` (``drives``: ``(n, n_drive)``);
2. without ``qacc``: ``mj_step``; with ``qacc`` (``(nv,)``, acceleration commands):
   ``mj_step1``, ``qacc`` into MuJoCo's, ``mj_rne(flg_acc=1)`` into ``tau``, the arm motors'
   torques ``tau[arm_v] + damping · qvel[arm_v]`` clipped to ``± limit``, ``mj_step2``;
3. ``qpos``, ``qvel`` and ``qfrc_actuator`` copied into row ``k`` of the three record arrays.

The library is built once per machine by the system compiler (``$CC``) against the MuJoCo
headers and library of the ``mujoco`` package and kept in :mod:`wbc.cbuild`'s cache; it links
to the very library the Python bindings loaded (same soname), so both act on the same
``mjModel`` / ``mjData``. The build refuses headers of another version than the loaded library
(``mjVERSION_HEADER`` against ``mujoco.mj_version()``). :func:`library` returns ``None`` — and
the plant keeps its Python loop — when there is no compiler, no headers or library, or the build
fails.

A MuJoCo error inside the loop (``mju_error``: by default it prints and exits the process)
returns to the plant, which raises ``mujoco.FatalError`` as the Python bindings do: the loop
installs a thread-local log handler for its duration (MuJoCo's exported
``_mjPRIVATE_setTlsLogHandler``, the bindings' own mechanism) that jumps back on an error and
passes warnings on to MuJoCo's global handler.
"""

from __future__ import annotations

import ctypes
import sys
from functools import cache
from pathlib import Path

from .. import cbuild

__all__ = ["SOURCE", "library"]

SOURCE = r"""
#include <setjmp.h>
#include <stdio.h>
#include <string.h>
#include <mujoco/mujoco.h>

#if mjVERSION_HEADER != WBC_MUJOCO_VERSION
#error "MuJoCo's headers are not the version of the library the Python bindings loaded"
#endif
_Static_assert(sizeof(mjtNum) == sizeof(double), "numpy's float64 arrays are mjtNum arrays");

/* exported by libmujoco, declared in no public header: the bindings' way to catch mju_error */
MJAPI mjfLogHandler _mjPRIVATE_setTlsLogHandler(mjfLogHandler handler);
MJAPI mjfLogHandler _mjPRIVATE_getGlobalLogHandler(void);

static _Thread_local jmp_buf failure;
static _Thread_local char failure_message[1024];
static _Thread_local mjfLogHandler outer;  /* this thread's handler before the call */

static void on_message(const mjLogMessage* message) {
  if (message->level == mjLOG_ERROR) {  /* worded as the bindings word it: "func: subject" */
    if (message->func) {
      snprintf(failure_message, sizeof(failure_message), "%s: %s", message->func,
               message->subject);
    } else {
      snprintf(failure_message, sizeof(failure_message), "%s", message->subject);
    }
    longjmp(failure, 1);
  }
  (outer ? outer : _mjPRIVATE_getGlobalLogHandler())(message);
}

/* n sub-steps (see the Python module's docstring); 0, or 1 after a MuJoCo error whose message
   is copied into error (error_size bytes) */
int wbc_substeps(const mjModel* m, mjData* d, int n,
                 int n_drive, const int* drive_u, const mjtNum* drives,
                 const mjtNum* qacc, mjtNum* tau,
                 int n_arm, const int* arm_v, const int* arm_u,
                 const mjtNum* damping, const mjtNum* limit,
                 mjtNum* qpos_rows, mjtNum* qvel_rows, mjtNum* force_rows,
                 char* error, int error_size) {
  outer = _mjPRIVATE_setTlsLogHandler(on_message);
  if (setjmp(failure)) {
    _mjPRIVATE_setTlsLogHandler(outer);
    snprintf(error, error_size, "%s", failure_message);
    return 1;
  }
  for (int k = 0; k < n; k++) {
    for (int i = 0; i < n_drive; i++) {
      d->ctrl[drive_u[i]] = drives[k * n_drive + i];
    }
    if (qacc) {
      mj_step1(m, d);
      memcpy(d->qacc, qacc, sizeof(mjtNum) * m->nv);
      mj_rne(m, d, 1, tau);
      for (int i = 0; i < n_arm; i++) {
        /* numpy's order: the product first, then the sum; then maximum, then minimum */
        mjtNum torque = tau[arm_v[i]] + damping[i] * d->qvel[arm_v[i]];
        torque = torque < -limit[i] ? -limit[i] : torque;
        d->ctrl[arm_u[i]] = torque > limit[i] ? limit[i] : torque;
      }
      mj_step2(m, d);
    } else {
      mj_step(m, d);
    }
    memcpy(qpos_rows + (size_t)k * m->nq, d->qpos, sizeof(mjtNum) * m->nq);
    memcpy(qvel_rows + (size_t)k * m->nv, d->qvel, sizeof(mjtNum) * m->nv);
    memcpy(force_rows + (size_t)k * m->nv, d->qfrc_actuator, sizeof(mjtNum) * m->nv);
  }
  _mjPRIVATE_setTlsLogHandler(outer);
  return 0;
}
"""

# no fused multiply-adds: the sums and products must round as numpy's separate operations do
FLAGS = ("-O2", "-ffp-contract=off", "-std=c11")


def _mujoco_files(mujoco) -> tuple[Path, Path] | None:
    """The ``mujoco`` package's include folder and shared library, if it ships them."""
    package = Path(mujoco.__file__).parent
    libraries = sorted(package.glob("libmujoco.so.*")) + sorted(package.glob("libmujoco.*.dylib"))
    if not (package / "include" / "mujoco" / "mujoco.h").exists() or not libraries:
        return None
    return package / "include", libraries[0]


def _build(mujoco) -> Path:
    """The library's path, built into :mod:`wbc.cbuild`'s cache first if needed
    (``RuntimeError`` when it cannot be)."""
    files = _mujoco_files(mujoco)
    if files is None:
        raise RuntimeError("the mujoco package ships no headers or shared library")
    include, shared = files
    flags = (*FLAGS, f"-DWBC_MUJOCO_VERSION={int(mujoco.mj_version())}", f"-I{include}")
    # linked by path (its soname is the one the bindings loaded); on Linux every symbol must
    # resolve at build time, so a MuJoCo without the log handler hook fails here, not at load
    link = (str(shared), f"-Wl,-rpath,{shared.parent}",
            *(("-Wl,--no-undefined",) if sys.platform.startswith("linux") else ()))
    return cbuild.cached_library("mujoco_substeps", SOURCE, flags, link)


@cache
def library():
    """The compiled ``wbc_substeps`` (a ``ctypes`` function; it returns 0, or 1 after a MuJoCo
    error), or ``None`` when it cannot be built or loaded here (the plant's Python loop then
    runs the same sub-steps). Built once per machine, loaded once per process."""
    import mujoco

    try:
        function = ctypes.CDLL(str(_build(mujoco))).wbc_substeps
    except (RuntimeError, OSError):
        return None
    pointer, integer = ctypes.c_void_p, ctypes.c_int
    function.argtypes = [pointer, pointer, integer, integer, pointer, pointer, pointer, pointer,
                         integer, pointer, pointer, pointer, pointer, pointer, pointer, pointer,
                         pointer, integer]
    function.restype = integer
    return function
