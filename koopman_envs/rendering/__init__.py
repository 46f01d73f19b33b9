"""The renderer: matplotlib frames of a scenario and its trajectories (renderer.py, blitting; scene.py,
one scenario's artists; layers.py, what a frame adds: lidar beams, collision marks, the view) and
their GIF/MP4 export (animation.py). One layer above the simulator core, below the env fronts, whose
``render()`` draws through it. Internal: the package exports ``Renderer`` and ``save_episode``."""
