"""Task graphs (the paper's section 2) and their execution (Algorithm 1)."""
