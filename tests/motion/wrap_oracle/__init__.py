"""Numpy oracles of the compiled wrapping (`motion.wrapping.wrapped_rows` and its wrap lines), on dual numbers."""
