"""Generation (paper §5): the species model — Dirichlet fits (``dirichlet``) of features measured
on a tree (``features``) in a ``SpeciesModel`` (``species``) — new trees grown in an envelope
(``growth``, ``envelopes``), their sway (``sway``) under wind or audio (``wind``), forests
(``forest``), and the batch of N trees (``batch``); new RGBA tree pictures from RGBA exemplars
(``exemplars``, ``mvc``, ``variations``; seed 000)."""
