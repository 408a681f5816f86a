"""Shared pytest fixtures. Never import bpy here: Blender runs only in spawned workers."""
