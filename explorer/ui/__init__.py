"""The page: trame + Vuetify state, controllers and layout. app.py's Studio owns the state and wires the panels
(compare.py, model_switch.py, latent_panel.py, exports.py; reads_as_panel.py's rows); each panel is given the Page
(panel_api.py: the session, the state, the controllers, `guarded`) and the few Studio callbacks it calls, never the
Studio itself. layout.py places the widgets from its LayoutParts; keys.py, playback.py and url_state.py act on what
their Protocol names."""
