"""Numerics of `garment`: bodies and LBS, motions, garments, geometry, deformers, metrics.

Pure numpy/scipy/torch. Never imports click, pyvista, imageio or pxr, never prints;
functions return values or raise `core.errors.InputError`.
"""
