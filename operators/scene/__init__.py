"""The bpy builders under the operators: the animated tree in the scene (:func:`build.build_tree`),
its exports and batch outputs, the clip editor's overlay and the outline read from an annotation.
No Operator classes here (those are in ``operators/*_op.py``)."""
