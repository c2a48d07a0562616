"""Pictures and videos of the worlds: `scenes` for the user's process, `drawing` for
the render worker that draws them (its own process, so no OpenGL library is loaded
into the user's), and `video` for episodes written as .mp4 or .gif files."""
