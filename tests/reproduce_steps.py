"""A step for ``wbc reproduce``'s runner in tests: prints the BLAS thread settings it was
started with and exits with the code its argument names."""

import os


def main(argv: list[str]) -> int:
    print({name: os.environ.get(name) for name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                                   "MKL_NUM_THREADS")})
    return int(argv[0])
