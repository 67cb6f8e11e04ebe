"""Implicit skinning (Vaillant et al. 2013) on OpenCL: the isk C++ library.

See docs/python.md. Geometry is float32 NumPy arrays, C-contiguous:
positions and normals (V, 3), triangles (F, 3), joint transforms (J, 4, 4).
"""

from ._isk import (
    Clip,
    Error,
    GeometricSkinner,
    ImplicitSkinner,
    InvalidArgumentError,
    Rig,
    SkinQuality,
    builtin_rig,
    builtin_rig_names,
    load_rig,
    quality,
)

__all__ = [
    "Clip",
    "Error",
    "GeometricSkinner",
    "ImplicitSkinner",
    "InvalidArgumentError",
    "Rig",
    "SkinQuality",
    "builtin_rig",
    "builtin_rig_names",
    "load_rig",
    "quality",
]
