"""Control references computed through the differentiable arm (optimal reaches)."""
