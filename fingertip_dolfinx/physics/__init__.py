"""The laws in UFL (kinematics, tissues, contact, pores, inertia) and the checks of a state."""
