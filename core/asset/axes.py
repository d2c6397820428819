"""The axes the engine files are written in, from Blender's (+Z up, right-handed, metres): glTF's
(+Y up, right-handed: ``(x, y, z)`` → ``(x, z, −y)``, a proper rotation) and Unreal's (+Z up,
left-handed, centimetres: ``(x, y, z)`` → ``100 (x, −y, z)``). Row vectors convert as ``v @ M.T``."""
from __future__ import annotations

import numpy as np

#: Blender → glTF
TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: Blender metres → Unreal centimetres
TO_UNREAL = np.diag([100.0, -100.0, 100.0])
