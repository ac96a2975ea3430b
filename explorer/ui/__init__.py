"""The page: trame + Vuetify state, controllers and layout. app.py's Studio owns the state and wires the panels
(compare.py, model_switch.py, latent_panel.py, reads_as_panel.py, exports.py, ...); layout.py places the widgets."""
