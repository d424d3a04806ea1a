"""Images (``images``) and figures and tables (``figures``), written through the base's atomic writer
(``hairdigi.render.domain.files``)."""
