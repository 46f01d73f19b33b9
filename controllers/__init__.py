"""Controllers for the KoopNav environments and the models they are built on.

``controllers.koopman`` learns bilinear Koopman models of the robot team from simulator data.
"""
