"""The bundled configs, installed as the package ``phri_spring.presets``.

Each ``*.yaml`` here is a preset that ``phri init --preset NAME`` writes out as a starter
config (``phri_spring.io.presets``); the files stay in ``configs/`` so that the paths the
README, docs and tests use keep working in a checkout.
"""
