from ._isk import (
    Clip as Clip,
    Error as Error,
    GeometricSkinner as GeometricSkinner,
    ImplicitSkinner as ImplicitSkinner,
    InvalidArgumentError as InvalidArgumentError,
    Rig as Rig,
    SkinQuality as SkinQuality,
    builtin_rig as builtin_rig,
    builtin_rig_names as builtin_rig_names,
    load_rig as load_rig,
    quality as quality,
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
