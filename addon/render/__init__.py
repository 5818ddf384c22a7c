"""Rendering with Mitsuba: the engine, its settings and panels, Export Mitsuba Scene (registered by ``addon``)."""
