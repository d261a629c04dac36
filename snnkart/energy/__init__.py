"""Energy estimates from measured operation counts: hardware profiles (per-operation prices
with their sources), counting from a deployment record, and pricing (count x price, with
provenance). numpy only; the report layer draws and writes what this computes."""
