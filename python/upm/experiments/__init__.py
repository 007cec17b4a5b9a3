"""Experiments: every demo and study that ``upm demo NAME`` runs, the scenarios of a sweep and the
sweeps themselves. :data:`upm.experiments.registry.EXPERIMENTS` is the one table of names; the
command line and the desk look names up there and own none.
"""
