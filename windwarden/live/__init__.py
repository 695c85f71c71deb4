"""The live system: the plant and supervisor as Zenoh nodes, the embedded router, and ``windwarden up``.

This is the edge where transport meets the pure core. The nodes call the same step contract as batch mode
(``wwcore.stepping``) on either side of the network; what goes over the wire is declared in ``wwcore.wire``; what
differs between plant kinds is one object per kind (``windwarden.kinds``). See ``docs/live.md``.
"""
