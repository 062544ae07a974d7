"""kinid package."""
