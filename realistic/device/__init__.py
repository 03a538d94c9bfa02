"""The OpenCL device layer, between ``core`` and ``camera``: imports ``core`` and ``errors`` only.

- ``opencl``: ``Device`` (one per process and ``--cl-device`` spec: context, program builds and
  their verified disk cache, buffers over numpy arrays), ``kernel_source``, ``whole_groups``.
"""
