"""Procedural greenhouse: layout, plants and peppers, scene.json, MJCF world, top view."""
