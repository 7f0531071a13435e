"""Cohesive interfaces on every facet: links, laws, star-local step solves."""
