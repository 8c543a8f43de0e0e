"""Flying the relay outside aerorelay's own simulation: the controller stepped from outside
(``stepper``), the frames an autopilot speaks (``frames``)."""
