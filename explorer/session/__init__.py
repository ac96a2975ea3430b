"""The session: one user's sequence, label, synthesis, distances, AFD and exports (session.py), and the latent map
(latent.py). No UI: the page (explorer/ui) talks to the session, never to the model directly."""
