"""Measurements and studies beside a campaign: bench, plant cost, studies."""
