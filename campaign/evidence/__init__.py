"""Evidence beyond counting (docs/evidence.md): certificate, rare events, falsification, hazard."""
