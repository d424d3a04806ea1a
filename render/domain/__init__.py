"""hairdigi's domain core: what a hair, a rig and a record are. numpy and the standard library only.

Every layer shares it: the Table 1 parameters (``params``) and their absorption ``sigma_a``
(``absorption``), the appearance beyond colour (``appearance``), the rig's geometry
(``rig_geometry``), atomic files and checked JSON reads (``files``), the version (``version``), the
base of the expected errors (``errors``) and the typed records that cross layers on disk
(``records``, their parts ``estimate_parts``, ``dye_record``; the checks of their fields and the
error a bad one raises, ``record_fields``).

It sits inside ``render/`` only because the repository's top level is fixed (``app/ hardware/
inference/ render/ resources/ tests/ packaging/``) and ``render`` is the bottom layer that every
other may import. The renderer, scenes and metrics sit above it in ``hairdigi.render``; ``hardware``
and ``inference`` above those; ``app`` on top. ``tests/test_layers.py`` holds it to numpy and the
standard library.
"""
