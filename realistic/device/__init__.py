"""The OpenCL device layer, between ``core`` and ``camera``: imports ``core`` and ``errors`` only.

- ``opencl``: ``Device`` (one per process and ``--cl-device`` spec: context, program builds and
  their verified disk cache, buffers over numpy arrays), ``kernel_source``, ``whole_groups``.
- ``pocl_cpu``: names PoCL's CPU for LLVM where LLVM 14 calls it "generic".
- ``pocl_interleave``: LLVM's interleave count for the lens kernel's work-item loop.
"""
