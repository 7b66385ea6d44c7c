"""Mobile manipulator models on pinocchio."""
