"""silpose.segment: background subtraction for real camera frames (paper section 6)."""
