"""A trained model scored on a split's test part: metrics, baselines, contact and texture scores, the report."""
