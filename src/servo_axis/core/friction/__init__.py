"""Friction laws used inside plant models: Maxwell-slip rolling friction, Coulomb, viscous."""
