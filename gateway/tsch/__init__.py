"""A TSCH network (IEEE 802.15.4 time-slotted channel hopping, as WirelessHART and ISA100.11a run
it): slotframes and cells, a central scheduler, link quality per channel, energy per slot type."""
