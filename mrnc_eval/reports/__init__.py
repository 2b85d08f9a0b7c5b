"""HTML/PDF reports, figures and tables, rendered from result objects only."""
