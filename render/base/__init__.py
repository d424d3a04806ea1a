"""The base layer below everything: numpy and the standard library only.

What every layer shares lives here: the Table 1 parameters (``params``), the rig's geometry
(``rig_geometry``), atomic files and checked JSON reads (``files``), the version (``version``), the
base of the expected errors (``errors``) and the typed records that cross layers on disk
(``records``). The renderer, scenes and metrics sit above it in ``hairdigi.render``; ``hardware``
and ``inference`` above those; ``app`` on top.
"""
