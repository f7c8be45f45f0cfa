"""Feedforward: the generator (reference + PTC + a sum of terms), PTC with a replaceable
model, the terms (friction table), the data-based friction table itself."""
