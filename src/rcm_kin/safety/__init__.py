"""Safety of automated motion: control barrier functions on the tool tip (a safety filter on
top of any nominal controller) and sum-of-squares barrier certificates for linear closed loops,
after the da Vinci safety thesis (AAU 2015; project digest) and Wieland and Allgower."""
