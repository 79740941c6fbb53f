"""Stage processors: each reads its inputs, calls compute kernels, and writes one new layer.

One module per processor; the CLI and batch runs call these functions.
"""
