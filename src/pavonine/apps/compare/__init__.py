"""Render comparisons: noise-aware and perceptual methods, approved baselines, HTML reports."""
