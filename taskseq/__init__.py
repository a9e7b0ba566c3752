"""taskseq: learning to sequence manipulation primitives for under-specified tasks (unrolled MRF + SSVM)."""
