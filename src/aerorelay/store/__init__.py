"""Files the program keeps: the cache folder with its locks, and run folders."""
