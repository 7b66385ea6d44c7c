"""Paper reproductions and timing studies."""
