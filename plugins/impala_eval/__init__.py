"""Mission evaluation: trajectory metrics against the truth, reports and plots."""
