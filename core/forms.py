"""Tree forms (issue 19): a broadleaf (a trunk forking into limbs), a conifer (a central leader
to the top with whorls of side branches) and a palm (one trunk with a crown of fronds from its
top). A reconstruction detects its form from frame 1's outline (:mod:`.reconstruct.form`) unless
one is given; the 3D lift, the species file and the generated trees follow it.
"""
from __future__ import annotations

#: what the panel and ``--form`` offer: ``auto`` detects it
FORMS = ("auto", "broadleaf", "conifer", "palm")
#: the forms a tree has
TREE_FORMS = FORMS[1:]


def form_of(conifer: bool, form: str | None = None) -> str:
    """The form of a tree or species recorded before forms existed: ``form`` when given, else
    ``"conifer"`` for ``conifer`` and ``"broadleaf"`` otherwise."""
    if form in TREE_FORMS:
        return str(form)
    return "conifer" if conifer else "broadleaf"
