"""(being written)"""
def code_actions(ctx, file, span):
    return None
