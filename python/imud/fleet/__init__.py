"""The fleet job: which units' calibrations no longer hold, over many recordings (issue 29)."""
