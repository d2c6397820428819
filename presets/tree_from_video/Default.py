import bpy

bpy.context.scene.tree_video.levels = 6
bpy.context.scene.tree_video.skeleton_kind = 'traced'
bpy.context.scene.tree_video.form = 'auto'
bpy.context.scene.tree_video.limbs = 'auto'
bpy.context.scene.tree_video.candidates = 32
bpy.context.scene.tree_video.solver = 'probabilistic'
bpy.context.scene.tree_video.sigma_track = 0.0075
bpy.context.scene.tree_video.sigma_shape = 0.04
bpy.context.scene.tree_video.max_step = 0.15
bpy.context.scene.tree_video.max_total = 0.785398
bpy.context.scene.tree_video.height_m = 10.0
bpy.context.scene.tree_video.fit_branches = True
bpy.context.scene.tree_video.build_mesh = True
bpy.context.scene.tree_video.scale = 1.0
bpy.context.scene.tree_video.twig_depth = 2
bpy.context.scene.tree_video.curliness = 0.3
bpy.context.scene.tree_video.bark = 'rough'
bpy.context.scene.tree_video.forks = 'joined'
bpy.context.scene.tree_video.build_leaves = True
bpy.context.scene.tree_video.leaf_density = 1.0
bpy.context.scene.tree_video.leaf_cards = 16
bpy.context.scene.tree_video.max_leaf_clusters = 1200
bpy.context.scene.tree_video.flutter_hz = 2.0
bpy.context.scene.tree_video.flutter_gain = 4.0
bpy.context.scene.tree_video.leaf_colour_mode = 'albedo'
bpy.context.scene.tree_video.leaf_colour_custom = (0.33, 0.46, 0.18)
