"""Fixtures of the hard suite come from tests/conftest.py (``variant``); nothing else is shared here."""
