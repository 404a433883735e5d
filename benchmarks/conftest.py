"""Benchmarks: every figure is measured beside its peer in the same run (see docs/performance.md)."""
