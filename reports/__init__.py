"""Reports: reproductions of the paper's tables and figures, and the comparison report."""
