"""Previews: the reference trace drawn over the artwork, as PNG.
"""
