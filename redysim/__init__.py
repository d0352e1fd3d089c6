"""redysim: O(n) dynamics of very long serial chains (DeNOC + Reverse Gaussian Elimination)."""
