"""Blender operators (the thin bpy layer over ``core``): the Operator modules (``*_op.py``, each with
one ``classes`` tuple, registered here in this order), the modal-job base they share
(:mod:`.jobs`), and in :mod:`.scene` the bpy builders they call (the tree in the scene, exports,
batch outputs, the clip overlay, the annotation outline)."""
import bpy

register, unregister = bpy.utils.register_submodule_factory(
    __name__, ["skeleton_op", "reconstruct_op", "export_op", "generate_op", "cut_op", "billboard_op"])
