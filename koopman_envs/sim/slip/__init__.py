"""The wheel slip of the robots (internal: the package exports ``SlipZone``; import from the
modules):

* :mod:`.sampling`: per-environment slip draws, block-buffered.
* :mod:`.schedule`: slip levels that change within an episode (a schedule, or random drift).
* :mod:`.zones`: slip zones, the regions of a map where the slip mean differs from the base level.
"""
