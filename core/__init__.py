"""The core: pure Python (numpy/scipy/OpenCV), no bpy. Stages, in the order data flows:

reconstruct/  video + outline → tracks → motion hierarchy → moving 2D skeleton (``Result``,
              ``Skeleton2D``: ``nodes2d (F, N, 2)`` px) → 3D lift (``Lift``: rest nodes, px) → 3D
              motion (``Motion``: ``nodes (F, N, 3)`` px); branch widths measured in frame 1, and
              frame 1's foreground (``Foreground``: the tree's pixels).
detail/       a ``Tree3D`` → the same tree with twigs copied from its forks, leaf clusters from
              frame 1's seeds filling its foreground (``LeafClusters``), leaf and bark colour as
              albedo, and its branch mesh (tubes, bark, curl).
generate/     reconstructed ``Tree3D``s → a species (``SpeciesModel``: Dirichlets of shape and
              motion) → new ``Tree3D``s grown in any envelope, swaying by wind or audio; forests;
              a crown's limbs grown where the video shows none (``limbs``); tree-cuts placed in
              a new tree that grows the rest around them (``cuts``, seed 001); and new RGBA tree
              pictures from RGBA exemplars (``variations``, seed 000).
asset/        a ``Tree3D`` → what every writer copies (``TreeAsset``): the rig (bones, rest pose,
              the motion's reduced keys; a bone budget's re-fitted rig), the branch and leaf meshes
              and their levels of detail, the look, each node's role; and what game engines read
              (``GameSettings`` and engine presets): Pivot Painter 2 elements and textures, the
              bone-animation texture, collision capsules, the impostor's layout and card, a packed
              GLB, the web viewer page; a tree-cut's branch mesh (``cut_mesh``). Blender's
              builders copy it; the engine files are written from it.
farm/         the record of a batch job (``JobRecord``: ``report.json`` and ``job.log``) and what
              makes two runs the same job (``identity``: input content hashes, settings hash, the
              re-run decision); imports no stage.

Shared by every stage, at this level: the tree model (``tree3d``: ``Tree3D``, ``LeafClusters``,
and its ``meta`` keys in ``meta``), a part of one kept to be placed in others (``tree_cut``:
``TreeCut``, its ``.npz`` file), its bones (``bones``), topology helpers (``topology``),
rotations (``rotations``), the envelope Ω (``envelope``), the outline (``outline``), file I/O
(``fileio``: atomic npz/JSON), the product's defaults and ranges (``params``), the output
formats' registry every writer and front end reads (``formats``), errors, progress
and background jobs. ``pipeline`` strings the stages end to end: ``run`` (the 2D stages) and
``build_3d`` (3D lift, motion, branch widths, twigs, leaves); between them ``with_limbs`` grows
the limbs of a crown that shows no bark. ``jobs`` describes a whole run as a typed job
(``ReconstructJob``, ``PhotoJob``, ``GenerateJob``, ``ExportJob``, ``VariationsJob``: inputs, settings, outputs asked
for), built from the batch options by name by one ``from_flat`` that the batch, a job file, the
farm and the API use.

Imports point one way: ``reconstruct`` never imports ``detail`` or ``generate``; ``detail`` may
use ``reconstruct``; ``generate`` may use both; ``asset`` uses ``detail`` only; the shared modules import no stage
(``tests/test_structure.py`` walks the imports).
"""
