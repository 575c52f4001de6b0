"""The bundled scenes (scene format v1), installed as package data."""
