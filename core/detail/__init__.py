"""Details of a reconstructed or generated tree: twigs copied from its own forks (``twigs``),
leaf clusters from frame 1's seeds (``leaf_seeds``) with their geometry and flutter
(``leaf_clusters``: a broadleaf's clusters, a palm's fronds, a conifer's needle sprays) and their
cards' textures (``leaf_texture``), and the branch mesh (``branch_mesh``) with its bark and curl shapes
(``shapes``)."""
