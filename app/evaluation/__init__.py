"""Evaluations of the whole chain against a hidden truth, and the benchmarks."""
