"""Surfaces as arrays: reading and safe repair, distances, closest points, inside tests."""
