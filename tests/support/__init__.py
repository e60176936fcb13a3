"""Helpers the tests share: reading vectors/ and their expectations."""
