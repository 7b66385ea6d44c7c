"""QP backends (persistent adapters) and closed-form reference solvers."""
