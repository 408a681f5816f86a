"""Reading the inputs of the workflows, each checked and reported in one line naming the file:

    images          a folder of PNG/JPG frames or a video file -> (N, H, W, 3) uint8 BGR stacks
    frames_folder   a multi-camera frames folder: background/<camera>/ and frames/<camera>/, matched to a rig
    silhouettes     per-camera folders of silhouette images (PNG, BMP, TIFF, JPEG) -> contours
    dataset         a dataset split as inference input -> contours
"""
