"""Stage 1: video to people's silhouettes (decoding, background subtraction, cleaning, the
noise floor, the optional person segmenter and the choice between them: sources.py)."""
