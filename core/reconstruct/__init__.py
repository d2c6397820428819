"""Reconstruction (paper §2–4 and Appendix A): the video read once (``video``), corners tracked
(``tracks``) with the bark statistics (``appearance``), the motion hierarchy by recursive
normalized cut (``hierarchy``), the moving 2D skeleton (``skeleton2d``: the paper's, or traced in
the image by ``trace`` with ``frame_evidence``), widths from frame 1 (``branch_fit``), the 3D lift
(``lift``) and the 3D motion (``motion``); ``run`` strings the 2D stages, ``cache`` keeps them,
``overlay`` draws them, ``skeleton_io`` saves them, ``auto_outline`` finds a tree without one
(``photo_outline`` in a photo)."""
