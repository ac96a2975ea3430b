"""Rendering: the 3D scene (PyVista, rendered on the server), its figures, the picture stream to the page
(trame-rca), the distance chart's markup and the studio's colours. No page state, no model."""
