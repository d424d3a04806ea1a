"""The review: the Qt-free model the window observes, its previews, and what every panel's model shares."""
