"""The papers' experiments: task grids, metrics and figures, run by ``limbctl eval`` alone."""
