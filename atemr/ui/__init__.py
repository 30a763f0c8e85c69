"""The operator dashboard: Flask application factory, blueprints and Socket.IO events."""
