"""Figures and paper-versus-revdem tables."""
