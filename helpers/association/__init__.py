"""Data association: compatibility tests and association algorithms."""
